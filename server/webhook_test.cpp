// Webhook pieces without a network: addresses and the allow-list, the signature, the backoff's bounds, and the outbox
// rows a job's end (and, when asked, a sequence's frame done) writes with the change itself.
#include "protocol/routes.h"
#include "server/database.h"
#include "server/scheduler.h"
#include "server/webhook_sender.h"
#include "server/webhook_post.h"
#include "server/webhook_url.h"

#include "tests/support/test_files.h"

#include <gtest/gtest.h>

#include <boost/asio/ip/tcp.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <set>
#include <thread>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

TEST(WebhookUrl, AddressesParseStrictly) {
  const WebhookUrl u = parse_webhook_url("https://Hooks.Example:8443/t?x=1");
  EXPECT_TRUE(u.https);
  EXPECT_EQ(u.host, "hooks.example");
  EXPECT_EQ(u.port, "8443");
  EXPECT_EQ(u.target, "/t?x=1");
  EXPECT_EQ(parse_webhook_url("http://[::1]/").host, "::1");
  EXPECT_EQ(parse_webhook_url("http://h").target, "/");
  EXPECT_EQ(parse_webhook_url("http://h").port, "80");
  for (const char* bad : {"ftp://h/", "http://", "http://u:p@h/", "http://h:0/", "http://h:99999/", "http://h/#f",
                          "http://h/a b", "https://[::1/"})
    EXPECT_THROW(parse_webhook_url(bad), std::invalid_argument) << bad;
}

TEST(WebhookUrl, TheAllowListMatchesSchemeHostPortAndPathPrefix) {
  const WebhookAllowList allow({"https://hooks.example/tessera/", "http://127.0.0.1:9000/"});
  allow.check("https://HOOKS.example:443/tessera/job-1");
  allow.check("http://127.0.0.1:9000/anything");
  for (const char* bad : {"http://hooks.example/tessera/x", "https://hooks.example/other", "https://hooks.example:444/tessera/",
                          "https://evil.example/tessera/", "http://127.0.0.1:9001/", "https://hooks.example@evil.example/tessera/"})
    EXPECT_THROW(allow.check(bad), std::invalid_argument) << bad;
  EXPECT_THROW(WebhookAllowList().check("https://hooks.example/"), std::invalid_argument);
}

TEST(WebhookSignature, IsHmacSha256InHex) {
  // RFC 4231, test case 2.
  EXPECT_EQ(hmac_sha256_hex("Jefe", "what do ya want for nothing?"),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
}

// A socket that takes connections (the kernel completes them) and never reads: a receiver that never answers.
struct SilentReceiver {
  boost::asio::io_context ioc;
  boost::asio::ip::tcp::acceptor acceptor{ioc, {boost::asio::ip::make_address("127.0.0.1"), 0}};
  std::string url() const { return "http://127.0.0.1:" + std::to_string(acceptor.local_endpoint().port()) + "/h"; }
};

TEST(WebhookPost, ASilentReceiverTimesOutAndAStopEndsTheAttempt) {
  SilentReceiver silent;
  const PostAnswer late = post_webhook(parse_webhook_url(silent.url()), "{}", {}, std::chrono::milliseconds(200));
  EXPECT_FALSE(late.status);
  EXPECT_EQ(late.error, "no answer within 200 ms");
  PostStopper stopper;
  std::thread stop([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    stopper.stop();
  });
  // An attempt that could wait ten minutes ends with the stop (or, stopped first, at once).
  const PostAnswer stopped =
      post_webhook(parse_webhook_url(silent.url()), "{}", {}, std::chrono::minutes(10), &stopper);
  stop.join();
  EXPECT_FALSE(stopped.status);
  EXPECT_EQ(stopped.error, "stopped");
  EXPECT_EQ(post_webhook(parse_webhook_url(silent.url()), "{}", {}, std::chrono::minutes(10), &stopper).error,
            "stopped");
}

// A delivery log that holds nothing: the sender's threads start and stop without work.
struct EmptyLog final : WebhookLog {
  std::vector<DueDelivery> due_deliveries(int64_t, size_t, const std::set<std::string>&) override { return {}; }
  void record_attempt(const std::string&, const std::string&, const DeliveryAttempt&) override {}
  std::vector<protocol::WebhookDelivery> deliveries(size_t) override { return {}; }
};

// A delivery log in memory: its rows in the order given (the oldest first), each attempt recorded in order.
struct ListLog final : WebhookLog {
  std::mutex mu;
  std::condition_variable cv;
  std::vector<DueDelivery> rows;      // (mu) pending until attempted
  std::vector<std::string> attempted;  // (mu) ids, in the order their attempts ended
  std::vector<DueDelivery> due_deliveries(int64_t, size_t limit, const std::set<std::string>& skip) override {
    std::lock_guard lock(mu);
    std::vector<DueDelivery> out;
    for (const DueDelivery& d : rows)
      if (out.size() < limit && !skip.count(d.url) &&
          std::find(attempted.begin(), attempted.end(), d.id) == attempted.end())
        out.push_back(d);
    return out;
  }
  void record_attempt(const std::string& id, const std::string&, const DeliveryAttempt&) override {
    std::lock_guard lock(mu);
    attempted.push_back(id);
    cv.notify_all();
  }
  std::vector<protocol::WebhookDelivery> deliveries(size_t) override { return {}; }
};

TEST(WebhookSender, AReceiverThatNeverAnswersHoldsAtMostItsShareOfTheThreads) {
  SilentReceiver silent;
  // An address where nothing listens: its attempts end at once (connection refused).
  std::string refused;
  {
    SilentReceiver closed;
    refused = closed.url();
  }
  ListLog log;
  for (int i = 0; i < 10; ++i) log.rows.push_back({"s" + std::to_string(i), silent.url(), "{}", 0});
  log.rows.push_back({"r", refused, "{}", 0});  // due after every delivery to the silent receiver
  WebhookSenderOptions o;
  o.threads = 4;
  o.per_address = 2;
  o.max_attempts = 1;
  o.timeout = std::chrono::minutes(10);  // the silent receiver's attempts end only when the sender does
  o.poll = std::chrono::milliseconds(20);
  {
    WebhookSender sender(log, o, [] { return int64_t(0); });
    std::unique_lock lock(log.mu);
    ASSERT_TRUE(log.cv.wait_for(lock, std::chrono::seconds(30), [&] { return !log.attempted.empty(); }))
        << "the other address's delivery waited behind the silent receiver's";
    EXPECT_EQ(log.attempted, std::vector<std::string>{"r"});
  }
  EXPECT_EQ(log.attempted, std::vector<std::string>{"r"});  // the silent receiver's attempts were stopped, not recorded
}

TEST(WebhookSender, BackoffDoublesUpToTheLimitWithJitter) {
  EmptyLog log;
  WebhookSenderOptions o;
  o.first_retry = std::chrono::milliseconds(1000);
  o.max_retry = std::chrono::milliseconds(10'000);
  WebhookSender sender(log, o, [] { return int64_t(0); });
  for (int64_t attempt = 1; attempt <= 40; ++attempt) {
    const int64_t full = std::min<int64_t>(int64_t(1000) << std::min<int64_t>(attempt - 1, 30), 10'000);
    const int64_t w = sender.backoff(attempt).count();
    EXPECT_GE(w, full / 2) << attempt;
    EXPECT_LE(w, full) << attempt;
  }
}

TEST(WebhookOutbox, AJobsEndIsStoredWithTheChangeForEachAddress) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-outbox-test-" + random_hex(6));
  {
    int64_t now = 3'000'000;
    DurableStore store(dir, Durability::process);
    SchedulerConfig config{10'000, 1, 1, ""};
    config.webhooks = {"http://farm.example/hook"};
    Scheduler s(config, [&] { return now; }, store);
    JobParams p;
    p.width = p.height = p.tile_size = 16;
    p.scene_hash = "h";
    p.pipeline.notify = "http://own.example/hook";
    const std::string a = s.add_job(p);
    EXPECT_TRUE(store.deliveries(10).empty());  // queued: no event
    ASSERT_EQ(s.cancel(a).status, CancelResult::cancelled);
    const std::vector<protocol::WebhookDelivery> rows = store.deliveries(10);
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_EQ(rows[0].id, rows[1].id);
    EXPECT_NE(rows[0].url, rows[1].url);
    for (const protocol::WebhookDelivery& d : rows) {
      EXPECT_EQ(d.event, "job.cancelled");
      EXPECT_EQ(d.job, a);
      EXPECT_EQ(d.state, "pending");
      EXPECT_EQ(d.created_ms, now);
    }
    ASSERT_EQ(store.due_deliveries(now, 10, {}).size(), 2u);
    EXPECT_EQ(store.due_deliveries(now, 10, {"http://farm.example/hook"}).size(), 1u);  // an address skipped
    EXPECT_TRUE(store.due_deliveries(now, 10, {"http://farm.example/hook", "http://own.example/hook"}).empty());
    store.record_attempt(rows[0].id, rows[0].url, {"pending", now + 500, 500, "answered 500"});
    EXPECT_EQ(store.due_deliveries(now, 10, {}).size(), 1u);  // the other one; this one is due later
    EXPECT_EQ(store.due_deliveries(now + 500, 10, {}).size(), 2u);
    // A job waiting for the cancelled one is blocked from the start: job.blocked to the farm's address only.
    JobParams q = p;
    q.pipeline.notify.clear();
    q.pipeline.after = {a};
    const std::string b = s.add_job(q);
    const std::vector<protocol::WebhookDelivery> more = store.deliveries(10);
    ASSERT_EQ(more.size(), 3u);
    EXPECT_EQ(more[0].event, "job.blocked");
    EXPECT_EQ(more[0].job, b);
    EXPECT_EQ(more[0].url, "http://farm.example/hook");
  }
  fs::remove_all(dir);
}

// Due deliveries come address by address and are merged by due time: the earliest first across addresses, at most
// `limit`, none of a skipped address (whose many rows are never read: the query per address starts at its own).
TEST(WebhookOutbox, DueDeliveriesMergeAddressesByTimeAndSkipFullOnes) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-outbox-test-" + random_hex(6));
  {
    DurableStore store(dir, Durability::process);
    SchedulerChanges c;
    const auto row = [&](const std::string& url, int64_t at) {
      c.outbox.push_back({"e" + std::to_string(c.outbox.size()), url, "job.done", "j", at, "{}"});
    };
    for (int64_t at = 1; at <= 500; ++at) row("http://full.example/hook", at);
    for (int64_t at : {3, 7}) row("http://b.example/hook", at);
    for (int64_t at : {2, 5, 9, 2000}) row("http://c.example/hook", at);
    store.apply(c);
    const auto seen = [](const std::vector<DueDelivery>& due) {
      std::vector<std::string> out;
      for (const DueDelivery& d : due) out.push_back(d.url.substr(7, 1) + d.id);
      return out;
    };
    // e500..e501 are b's, e502..e505 c's.
    EXPECT_EQ(seen(store.due_deliveries(1000, 4, {"http://full.example/hook"})),
              (std::vector<std::string>{"ce502", "be500", "ce503", "be501"}));
    EXPECT_EQ(seen(store.due_deliveries(1000, 10, {"http://full.example/hook"})),
              (std::vector<std::string>{"ce502", "be500", "ce503", "be501", "ce504"}));  // c's at 2000 is not due
    EXPECT_EQ(seen(store.due_deliveries(3, 5, {})),
              (std::vector<std::string>{"fe0", "fe1", "ce502", "fe2", "be500"}));  // equal times: in insertion order
    EXPECT_TRUE(store.due_deliveries(1000, 4, {"http://full.example/hook", "http://b.example/hook",
                                               "http://c.example/hook"}).empty());
  }
  fs::remove_all(dir);
}

TEST(WebhookOutbox, ASequenceAskingForFramesTellsItsOwnAddressOfEachFrameDone) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-outbox-test-" + random_hex(6));
  {
    int64_t now = 5'000'000;
    DurableStore store(dir, Durability::process);
    SchedulerConfig config{10'000, 1, 1, ""};
    config.webhooks = {"http://farm.example/hook"};
    Scheduler s(config, [&] { return now; }, store);
    JobParams p;
    p.tile_size = 16;  // one tile a frame
    p.pipeline.notify = "http://own.example/hook";
    p.pipeline.notify_frames = true;
    const std::string seq = s.add_sequence(p, {{1, 16, 16, 1, "h1"}, {2, 16, 16, 1, "h2"}});
    JobParams q = p;
    q.pipeline.notify_frames = false;  // the default: frames are not told
    const std::string quiet = s.add_sequence(q, {{1, 16, 16, 1, "h1"}});
    const std::string w = s.register_worker("a").id;
    const auto render = [&](const std::string& frame_job) {
      const AcquireResult r = s.acquire(w);
      ASSERT_EQ(r.status, AcquireResult::granted);
      ASSERT_EQ(r.lease.job, frame_job);
      ASSERT_EQ(s.claim_result(r.lease.id).status, ResultClaim::proceed);
      s.finish_result(r.lease.id, 0, "pixels");
      ++now;
      s.complete_job(frame_job);
    };
    render(frame_job_id(seq, 1));
    std::vector<protocol::WebhookDelivery> rows = store.deliveries(10);
    ASSERT_EQ(rows.size(), 1u);  // stored with the frame's completion, to the job's own address only
    EXPECT_EQ(rows[0].event, "frame.done");
    EXPECT_EQ(rows[0].job, seq);
    EXPECT_EQ(rows[0].url, "http://own.example/hook");
    EXPECT_EQ(rows[0].created_ms, now);
    const std::vector<DueDelivery> due = store.due_deliveries(now, 10, {});
    ASSERT_EQ(due.size(), 1u);
    const nlohmann::json body = nlohmann::json::parse(due[0].body);
    EXPECT_EQ(body["event"], "frame.done");
    EXPECT_EQ(body["frame"], 1);
    EXPECT_EQ(body["job"]["id"], frame_job_id(seq, 1));
    EXPECT_EQ(body["job"]["state"], "done");
    EXPECT_EQ(body["links"]["result"], protocol::routes::job_frame_result(seq, 1));
    render(frame_job_id(seq, 2));  // the last frame: its frame.done, then the sequence's job.done to both addresses
    rows = store.deliveries(10);
    ASSERT_EQ(rows.size(), 4u);
    std::multiset<std::string> events;
    for (const protocol::WebhookDelivery& d : rows) events.insert(d.event);
    EXPECT_EQ(events, (std::multiset<std::string>{"frame.done", "frame.done", "job.done", "job.done"}));
    render(frame_job_id(quiet, 1));  // no frame.done: only the job's end, to both addresses
    rows = store.deliveries(10);
    ASSERT_EQ(rows.size(), 6u);
    for (size_t i = 0; i < 2; ++i) {
      EXPECT_EQ(rows[i].event, "job.done");
      EXPECT_EQ(rows[i].job, quiet);
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace tessera::server
