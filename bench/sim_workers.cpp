// Capacity of one coordinator: N simulated workers drive the real farm protocol against a real `tessera serve` on
// loopback and we measure what the coordinator spends. Each simulated worker is a coroutine on one of --loop-threads
// event-loop threads (4 by default; workers dealt round-robin), with its own keep-alive connection (AsyncConnection:
// HttpClient's requests, byte for byte), doing what `tessera worker` does, minus the rendering: register, ask for a
// lease (backing off 100 ms .. 2 s with jitter on 204) naming the job whose spec it holds, so that the first lease of
// another job brings that job's spec (with --spec-by-get: bare leases and a GET of the spec once per job), "render"
// by napping the tile time while heartbeating every heartbeat period, then upload a valid precomputed tile EXR of
// the leased window (uncompressed float32, as workers send it; each tile's bytes encoded once and shared), asking in
// the same request for the next lease (X-Tessera-Next-Lease), which its answer carries when one is granted: one
// request per tile in the steady state. With --two-requests uploads ask for nothing and every lease is a lease request
// of its own, which is also what `tessera worker` sends in the steady state (it asks for its next lease near the end
// of a render, so that the next render can begin on threads the current one leaves idle). A feeder
// thread keeps at least two jobs and 2N pending tiles queued. For every N it prints request latency p50/p99 per
// route, the coordinator's CPU use (from /proc/<pid>/stat) and the tile rate.
//
//   ./build/bench/sim_workers --tessera build/cli/tessera [--workers 10,50,200,500] [--seconds 15] [--warmup 4]
//       [--tile-seconds 2] [--heartbeat-seconds 1] [--image 2048] [--tile 64] [--data-dir DIR] [--spec-by-get]
//       [--loop-threads 4] [--two-requests]
//
// The simulated workers share the machine with the coordinator; their own CPU use is printed too (per window and per
// tile), so a row where the clients starve the coordinator can be told apart from one where the coordinator is the
// limit, and so is the event loops' lag (how late a nap's timer ran after its due time, p99): a loop that is late
// reads answers late too, and a latency near its lag is the simulator's, not the coordinator's.
//
// With --share, the farm is shared by two users of a users file (docs/protocol.md, "Sharing the farm"): ana submits
// one --big-tiles job at the start, ben a --small-tiles job every --small-every seconds, and the run reports each
// user's part of the worker time while both have work, each small job's time to its first tile, and the tile rate;
// --one-user submits both as ana (one owner: strict priority, then age) for the comparison.
//
// With --hanging-webhooks N, the first farm size runs four times, A B A B: A without webhooks, B with the
// coordinator's webhook (serve --webhook) pointing at a receiver in this process that accepts connections and never
// answers. In both, a stream of job events runs beside the workers (N + 20 jobs submitted and cancelled at once at the
// start, then 4 a second; each cancellation is a delivery to every webhook), so that in B at least N deliveries are
// pending while the window is measured. It prints tiles/s and request p99 for each run and variant, and B / A.
#include "core/image/image.h"
#include "core/util/sha256.h"
#include "protocol/messages.h"
#include "protocol/routes.h"
#include "protocol/webhook.h"
#include "worker/child_process.h"
#include "client/http_client.h"
#include "bench/async_connection.h"

#include <CLI/CLI.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/redirect_error.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <nlohmann/json.hpp>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
namespace asio = boost::asio;
using tessera::bench::AsyncConnection;
using tessera::client::HttpClient;
using tessera::client::HttpRequest;
using tessera::client::TransportError;
using tessera::client::HttpResponse;
namespace protocol = tessera::protocol;
namespace routes = tessera::protocol::routes;

namespace {

/// The run's settings (command line).
struct Options {
  fs::path tessera;                                 ///< The tessera binary (runs `serve`).
  std::vector<int> worker_counts{10, 50, 200, 500};  ///< Simulated farm sizes, one coordinator run each.
  double seconds = 15;           ///< Measured window per farm size.
  double warmup = 4;             ///< Unmeasured time before the window (registration, first leases).
  double tile_seconds = 2;       ///< Simulated render time per tile (jittered +-20%).
  int heartbeat_seconds = 1;     ///< Heartbeat period announced by the coordinator (--heartbeat-seconds).
  int image = 2048;              ///< Square image edge of each job, in pixels.
  int tile = 64;                 ///< Tile edge, in pixels.
  fs::path data_dir;             ///< Where coordinator data folders go (default: a temporary folder).
  bool spec_by_get = false;      ///< Bare lease requests and a GET of the spec per job (workers before the spec came
                                 ///< with the lease).
  bool share = false;            ///< Two users share the farm (the big and the small jobs) instead of the feeder's.
  bool one_user = false;         ///< With share: both users' jobs submitted by the first (strict priority).
  double small_every = 60;       ///< With share: seconds between the second user's small jobs.
  int small_tiles = 200;         ///< With share: tiles of each small job (a row of tiles: small_tiles x 1).
  int big_tiles_edge = 100;      ///< With share: the big job is big_tiles_edge x big_tiles_edge tiles.
  int hanging_webhooks = 0;      ///< >0: the A/B run with a receiver that never answers, this many deliveries pending.
  int loop_threads = 4;          ///< Event-loop threads driving the simulated workers (each worker on one of them).
  bool two_requests = false;     ///< Uploads do not ask for the next lease: a lease request per tile besides the upload.
};

/// The request kinds we time separately.
enum Route { kRegister, kLease, kLease204, kSpec, kHeartbeat, kUpload, kRouteCount };
const char* const kRouteNames[kRouteCount] = {"register", "lease 200", "lease 204", "spec", "heartbeat", "upload"};

/// One simulated worker's measurements inside the window.
struct WorkerTally {
  std::vector<float> latency_ms[kRouteCount];  ///< Per-route request latencies (ms).
  std::vector<float> lag_ms;   ///< How late the event loop ran each of the worker's naps after its due time (ms).
  int64_t tiles_accepted = 0;  ///< Uploads answered accepted or duplicate.
  int64_t upload_bytes = 0;    ///< Bytes of those uploads.
  int64_t errors = 0;          ///< Transport failures or unexpected statuses.
  std::string first_error;     ///< The first of them, for the report.
  /// Every accepted tile: its job, when its lease was granted and when its upload was answered (a shared farm's
  /// report counts worker time by owner).
  struct Span {
    std::string job;
    Clock::time_point granted, done;
  };
  std::vector<Span> spans;
};

/// What the whole farm did in one window.
struct RunResult {
  int workers = 0;                    ///< N.
  double window_seconds = 0;          ///< Measured wall time.
  double coordinator_cpu_seconds = 0; ///< utime + stime of `tessera serve` over the window.
  double client_cpu_seconds = 0;      ///< This process's CPU over the window.
  WorkerTally total;                  ///< All workers' tallies merged.
  std::map<std::string, std::pair<std::string, Clock::time_point>> jobs;  ///< With share: job -> (owner, submitted).
  Clock::time_point window_start, window_end;  ///< The window.
  int64_t job_events = 0;             ///< With hanging webhooks: jobs submitted and cancelled for their events.
  int64_t deliveries = 0;             ///< Webhook deliveries the coordinator listed at the window's end.
  int64_t pending_deliveries = 0;     ///< Of them, those still pending.
  std::string metrics_start, metrics_end;  ///< The coordinator's /metrics at the window's start and end.
};

/// A tile EXR for every window of each job geometry added, encoded once and shared by all simulated workers.
class TileBank {
 public:
  /// Encodes every tile of a width x height job cut into tile x tile squares (uncompressed float32, constant grey).
  void add(int width, int height, int tile) {
    for (int y0 = 0; y0 < height; y0 += tile) {
      for (int x0 = 0; x0 < width; x0 += tile) {
        const tessera::PixelWindow w{x0, y0, std::min(x0 + tile, width), std::min(y0 + tile, height)};
        tessera::Image img = tessera::Image::make(w.width(), w.height());
        std::fill(img.rgb.begin(), img.rgb.end(), 0.25f);
        tessera::ExrWriteOptions wo;
        wo.compression = tessera::ExrCompression::kNone;
        wo.display_window = {0, 0, width, height};
        wo.data_window = w;
        const std::vector<uint8_t> bytes = tessera::encode_exr(img, wo);
        tiles_[{width, height, x0, y0}] = std::string(bytes.begin(), bytes.end());
      }
    }
  }
  /// The encoded tile for a window leased of a width x height job; throws std::out_of_range for another geometry.
  const std::string& at(int width, int height, const std::array<int, 4>& window) const {
    return tiles_.at({width, height, window[0], window[1]});
  }

 private:
  std::map<std::array<int, 4>, std::string> tiles_;  // (job width, height, x0, y0) -> EXR
};

/// CPU seconds (user + system) that process pid has used, from /proc/<pid>/stat; -1 when unreadable.
double process_cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t close = text.rfind(')');  // the command name may contain spaces; fields follow its ')'
  if (close == std::string::npos) return -1;
  std::istringstream fields(text.substr(close + 2));
  std::string skip;
  for (int i = 3; i < 14; ++i) fields >> skip;  // fields 3..13
  long long utime = 0, stime = 0;
  fields >> utime >> stime;                      // fields 14 and 15, in clock ticks
  return double(utime + stime) / double(sysconf(_SC_CLK_TCK));
}

/// CPU seconds this process has used.
double self_cpu_seconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

/// A webhook receiver that accepts connections and never answers (nor reads them): every delivery to it lasts the
/// sender's whole timeout. Counts the connections it accepted; closes them when destroyed.
class HangingReceiver {
 public:
  HangingReceiver() {
    fd_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    if (fd_ < 0 || bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || listen(fd_, 1024) != 0 ||
        getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0)
      throw std::runtime_error("cannot listen for the hanging webhook receiver");
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { loop(); });
  }
  ~HangingReceiver() {
    stop_ = true;
    thread_.join();
    for (int c : conns_) close(c);
    close(fd_);
  }
  HangingReceiver(const HangingReceiver&) = delete;
  HangingReceiver& operator=(const HangingReceiver&) = delete;
  /// The address to give `serve --webhook`.
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/hook"; }
  /// Connections accepted so far.
  int64_t accepted() const { return accepted_.load(); }

 private:
  void loop() {
    while (!stop_.load()) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      const int c = accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (c < 0) continue;
      conns_.push_back(c);
      ++accepted_;
    }
  }
  int fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> accepted_{0};
  std::vector<int> conns_;  // (loop's thread until joined)
  std::thread thread_;      // last: starts after the rest is ready
};

/// A small sphere scene (no assets) of the given size: the coordinator validates it like any submission.
std::string job_body(int width, int height, int tile, const std::string& name, int priority = 0) {
  json scene = {
      {"integrator", {{"type", "intersection_test"}, {"spp", 1}, {"point_light_position", {0, 3, 3}},
                      {"point_light_flux", {40, 40, 40}}}},
      {"film", {{"resolution", {width, height}}}},
      {"camera", {{"position", {0, 0.3, 4}}, {"look_at", {0, 0, 0}}, {"fov", 45}}},
      {"textures", {{"white", {{"type", "constant"}, {"color", {0.8, 0.7, 0.6}}}}}},
      {"materials", {{"m", {{"type", "diffuse"}, {"texture_name", "white"}}}}},
      {"objects", {{{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 0.7}, {"material_name", "m"}}}}};
  protocol::JobSubmission job;
  job.scene = std::move(scene);
  job.tile_size = tile;
  job.name = name;
  job.priority = priority;
  return json(job).dump();
}

/// Shared state of one run.
struct Farm {
  /// A farm for these settings and tiles, talking to the coordinator at url.
  Farm(const Options& o, const TileBank& b, tessera::client::HttpUrl u) : opt(o), bank(b), url(std::move(u)) {}
  const Options& opt;
  const TileBank& bank;
  tessera::client::HttpUrl url;
  asio::ip::tcp::resolver::results_type endpoints;  ///< url's host, resolved once for the workers' connections.
  int workers = 0;  ///< N, for the feeder's supply of pending tiles.
  std::atomic<bool> stop{false};
  std::mutex stop_mu;                  ///< With stop_cv: the feeders' naps end at once when the farm stops.
  std::condition_variable stop_cv;
  Clock::time_point window_start, window_end;  ///< Measurements count only between these.
  std::string worker_token, big_token, small_token;  ///< With share: the users' tokens (else none are needed).
  /// A job the feeders submitted.
  struct Job {
    int width = 0, height = 0;   ///< Its image.
    std::string owner;           ///< "big" or "small": whose job it is in the share report.
    Clock::time_point submitted; ///< When its submission was answered.
  };
  std::mutex jobs_mu;
  std::map<std::string, Job> jobs;  ///< (jobs_mu) every job submitted, by id
  /// Submits a width x height job through `http` and records it; throws on a refusal.
  std::string submit(HttpClient& http, int width, int height, const std::string& owner, int priority = 0) {
    const HttpResponse r = http.send("POST", routes::jobs(), job_body(width, height, opt.tile, owner, priority));
    if (r.status != 201) throw std::runtime_error("POST " + routes::jobs() + " answered " + r.error_text());
    const std::string id = protocol::parse_answer<protocol::SubmitAnswer>(r.body, "submission").id;
    std::lock_guard lock(jobs_mu);
    jobs[id] = Job{width, height, owner, Clock::now()};
    return id;
  }
  /// The image size of a submitted job.
  std::pair<int, int> size_of(const std::string& id) {
    std::lock_guard lock(jobs_mu);
    const Job& j = jobs.at(id);
    return {j.width, j.height};
  }
};

/// Sleeps d (a feeder's thread) unless the farm stops first; false when stopped.
bool nap(Farm& farm, Clock::duration d) {
  std::unique_lock lock(farm.stop_mu);
  return !farm.stop_cv.wait_for(lock, d, [&] { return farm.stop.load(); });
}

/// Stops the farm: every nap ends.
void stop_farm(Farm& farm) {
  {
    std::lock_guard lock(farm.stop_mu);
    farm.stop = true;
  }
  farm.stop_cv.notify_all();
}

/// One event-loop thread and the simulated workers it drives: a nap timer for each of them (cancelled when the farm
/// stops, so that every nap ends at once).
struct Loop {
  asio::io_context ioc{1};              ///< Run by one thread.
  std::deque<asio::steady_timer> naps;  ///< One per worker of this loop.
  std::thread thread;                   ///< Runs ioc until its workers have all returned.
};

/// A simulated worker's nap: d on its timer unless the farm stops first; false when stopped. A nap that ends inside
/// the window records how late the loop ran it after its due time (the loop's lag).
asio::awaitable<bool> nap(Farm& farm, asio::steady_timer& timer, Clock::duration d, WorkerTally& tally) {
  if (farm.stop.load()) co_return false;
  timer.expires_after(d);
  boost::system::error_code ec;
  co_await timer.async_wait(asio::redirect_error(asio::use_awaitable, ec));
  if (ec) co_return false;  // cancelled: the farm stops
  const auto now = Clock::now();
  if (timer.expiry() >= farm.window_start && now <= farm.window_end)
    tally.lag_ms.push_back(std::chrono::duration<float, std::milli>(now - timer.expiry()).count());
  co_return !farm.stop.load();
}

/// Sends request (with body) on http and records its latency under route (lease 204s apart) when the request started
/// and was answered inside the window: from the request's first byte written to the answer's last byte read.
asio::awaitable<HttpResponse> timed_send(Farm& farm, WorkerTally& tally, AsyncConnection& http, Route route,
                                         const HttpRequest& request, std::string_view body) {
  const auto t0 = Clock::now();
  HttpResponse r = co_await http.send(request, body);
  const auto t1 = Clock::now();
  if (t0 >= farm.window_start && t1 <= farm.window_end) {
    tally.latency_ms[route == kLease && r.status == 204 ? kLease204 : route].push_back(
        std::chrono::duration<float, std::milli>(t1 - t0).count());
  }
  co_return r;
}

/// One simulated worker: the protocol loop of `tessera worker` with naps in place of rendering, on its own keep-alive
/// connection, as a coroutine of one event loop.
asio::awaitable<void> simulated_worker(Farm& farm, int index, WorkerTally& tally, asio::steady_timer& timer) {
  AsyncConnection http(co_await asio::this_coro::executor, farm.url, farm.endpoints);
  http.set_bearer_token(farm.worker_token);
  std::mt19937_64 rng(0x5eed0000u + unsigned(index));
  auto error = [&](const std::string& what) {
    ++tally.errors;
    if (tally.first_error.empty()) tally.first_error = what;
  };
  const auto send = [&](Route route, const HttpRequest& request) {
    return timed_send(farm, tally, http, route, request, request.body);
  };

  std::string id, secret;
  int heartbeat_seconds = 5;
  std::string spec_job;  // the job whose spec we have "cached"
  std::chrono::milliseconds idle{100};
  std::optional<protocol::LeaseAnswer> carried;  // the next lease, granted with the last upload's answer
  while (!farm.stop.load()) {
    Clock::duration pause{};  // a nap before the next round (no co_await inside a handler)
    try {
      if (id.empty()) {
        carried.reset();
        const json reg = protocol::WorkerHello{"sim-" + std::to_string(index), 1, "sim", {}};
        const HttpResponse r =
            co_await send(kRegister, tessera::client::make_request("POST", routes::workers(), reg.dump()));
        if (r.status != 201) {
          error("register answered " + r.error_text());
          co_await nap(farm, timer, 1s, tally);
          continue;
        }
        const auto registration = protocol::parse_answer<protocol::Registration>(r.body, "registration");
        id = registration.id;
        secret = registration.secret;
        heartbeat_seconds = int(registration.heartbeat_seconds);
      }
      // What a lease request asks for, in its body or with an upload: the spec of any job but the one held.
      const auto asked = [&] {
        protocol::LeaseRequest req;
        if (!farm.opt.spec_by_get) req.known_jobs = spec_job.empty() ? std::vector<std::string>{} : std::vector{spec_job};
        return req;
      };
      const auto as_worker = [&secret](std::string method, std::string target, std::string body) {
        HttpRequest req{std::move(method), std::move(target), std::move(body), "application/json", {}};
        req.headers[protocol::kWorkerSecretHeader] = secret;
        return req;
      };
      if (!carried) {
        const std::string asked_body = farm.opt.spec_by_get ? std::string() : json(asked()).dump();
        const HttpResponse r = co_await send(kLease, as_worker("POST", routes::worker_lease(id), asked_body));
        if (r.status == 204) {
          std::uniform_int_distribution<long long> pick(idle.count() / 2, idle.count());
          co_await nap(farm, timer, std::chrono::milliseconds(pick(rng)), tally);
          idle = std::min<std::chrono::milliseconds>(idle * 2, 2000ms);
          continue;
        }
        if (r.status == 404) { id.clear(); continue; }
        if (r.status != 200) {
          error("lease answered " + r.error_text());
          co_await nap(farm, timer, 1s, tally);
          continue;
        }
        carried = protocol::parse_answer<protocol::LeaseAnswer>(r.body, "lease");
      }
      idle = 100ms;
      const protocol::LeaseAnswer answer = std::move(*std::exchange(carried, std::nullopt));
      const protocol::Lease& lease = answer.lease;
      if (answer.spec) spec_job = lease.job;
      const std::string& lease_id = lease.id;
      const std::string& job = lease.job;
      const std::array<int, 4> window = {lease.window.x0, lease.window.y0, lease.window.x1, lease.window.y1};
      const auto granted = Clock::now();
      if (job != spec_job) {
        const HttpResponse s = co_await send(kSpec, tessera::client::make_request("GET", routes::job_spec(job)));
        if (s.status != 200) { error("spec answered " + s.error_text()); continue; }
        spec_job = job;
      }
      // "Render": the tile time (+-20%), heartbeating every heartbeat period.
      std::uniform_real_distribution<double> jitter(0.8, 1.2);
      const auto done = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(farm.opt.tile_seconds * jitter(rng)));
      bool revoked = false;
      while (!farm.stop.load() && Clock::now() < done) {
        const auto next = std::min(done, Clock::now() + std::chrono::seconds(heartbeat_seconds));
        if (!co_await nap(farm, timer, next - Clock::now(), tally)) break;
        if (Clock::now() >= done) break;
        const std::string report = json(protocol::HeartbeatReport{4096}).dump();
        const HttpResponse h = co_await send(kHeartbeat, as_worker("POST", routes::lease_heartbeat(lease_id), report));
        if (h.status == 410) { revoked = true; break; }
        if (h.status != 200) error("heartbeat answered " + h.error_text());
      }
      if (farm.stop.load() || revoked) continue;
      const auto [job_width, job_height] = farm.size_of(job);
      const std::string& exr = farm.bank.at(job_width, job_height, window);  // shared: sent without a copy
      HttpRequest up;
      up.method = "PUT";
      up.target = routes::lease_result(lease_id);
      up.content_type = "image/x-exr";
      up.headers[protocol::kRaysHeader] = "4096";
      up.headers[protocol::kWorkerSecretHeader] = secret;
      if (!farm.opt.two_requests) up.headers[protocol::kNextLeaseHeader] = protocol::next_lease_header(asked());
      const auto t0 = Clock::now();
      const HttpResponse u = co_await timed_send(farm, tally, http, kUpload, up, exr);
      if (u.status == 200) {
        if (!farm.opt.two_requests) carried = protocol::parse_answer<protocol::ResultAnswer>(u.body, "result").next;
        tally.spans.push_back({job, granted, Clock::now()});
        if (t0 >= farm.window_start && Clock::now() <= farm.window_end) {
          ++tally.tiles_accepted;
          tally.upload_bytes += int64_t(exr.size());
        }
      } else if (u.status != 410) {
        error("upload answered " + u.error_text());
      }
    } catch (const std::exception& e) {
      error(e.what());
      carried.reset();
      pause = 500ms;
    }
    if (pause != Clock::duration{}) co_await nap(farm, timer, pause, tally);
  }
}

/// Keeps at least two unfinished jobs on the coordinator so that workers always find work.
void feeder(Farm& farm, WorkerTally& tally) {
  HttpClient http(farm.url);
  while (!farm.stop.load()) {
    try {
      const HttpResponse r = http.send("GET", routes::jobs());
      int unfinished = 0;
      int64_t pending = 0;
      if (r.status == 200) {
        for (const protocol::JobStatus& j : protocol::parse_answer<protocol::JobList>(r.body, "job list").jobs) {
          if (j.finished()) continue;
          ++unfinished;
          pending += j.tiles.pending;
        }
      }
      // At least two unfinished jobs, and enough pending tiles that no worker waits for the next check.
      const int64_t per_job = int64_t((farm.opt.image + farm.opt.tile - 1) / farm.opt.tile) *
                              ((farm.opt.image + farm.opt.tile - 1) / farm.opt.tile);
      while (unfinished < 2 || pending < 2 * int64_t(farm.workers)) {
        farm.submit(http, farm.opt.image, farm.opt.image, "sim_workers");
        ++unfinished;
        pending += per_job;
      }
    } catch (const std::exception& e) {
      ++tally.errors;
      if (tally.first_error.empty()) tally.first_error = std::string("feeder: ") + e.what();
    }
    nap(farm, 500ms);
  }
}

/// Job events for the webhooks, the same with and without them: one-tile jobs submitted and cancelled at once (lowest
/// priority, so that a worker leases one only when it has nothing else; each cancellation is a delivery to every
/// webhook), `burst` of them at the start, then 4 a second until the farm stops.
void job_events(Farm& farm, WorkerTally& tally, int burst, std::atomic<int64_t>& count) {
  HttpClient http(farm.url);
  const auto one = [&] {
    const std::string id = farm.submit(http, farm.opt.tile, farm.opt.tile, "event", -1000);
    const HttpResponse c = http.send("DELETE", routes::job(id));
    if (c.status != 200) throw std::runtime_error("DELETE " + routes::job(id) + " answered " + c.error_text());
    ++count;
  };
  try {
    for (int i = 0; i < burst && !farm.stop.load(); ++i) one();
    while (nap(farm, 250ms)) one();
  } catch (const std::exception& e) {
    ++tally.errors;
    if (tally.first_error.empty()) tally.first_error = std::string("job events: ") + e.what();
  }
}

/// A shared farm's submissions: the big user's job at once, then the small user's every small_every seconds.
void share_feeder(Farm& farm, WorkerTally& tally) {
  HttpClient big(farm.url), small(farm.url);
  big.set_bearer_token(farm.big_token);
  small.set_bearer_token(farm.opt.one_user ? farm.big_token : farm.small_token);
  const int edge = farm.opt.big_tiles_edge * farm.opt.tile;
  try {
    farm.submit(big, edge, edge, "big");
    for (Clock::time_point next = farm.window_start; nap(farm, next - Clock::now());) {
      farm.submit(small, farm.opt.small_tiles * farm.opt.tile, farm.opt.tile, "small");
      next += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(farm.opt.small_every));
    }
  } catch (const std::exception& e) {
    ++tally.errors;
    if (tally.first_error.empty()) tally.first_error = std::string("share feeder: ") + e.what();
  }
}

/// Waits up to 30 s for the coordinator's ready file; returns its "host:port" or "" on timeout or exit.
std::string wait_ready(const fs::path& ready, tessera::worker::ChildProcess& serve) {
  for (int i = 0; i < 600; ++i) {
    std::ifstream in(ready);
    std::string line;
    if (in && std::getline(in, line) && !line.empty()) return line;
    if (tessera::worker::child_exited(serve)) return {};
    std::this_thread::sleep_for(50ms);
  }
  return {};
}

/// Runs one coordinator with n simulated workers (and with opt.hanging_webhooks, the job events; its deliveries go to
/// `webhook` when not empty); throws std::runtime_error when the coordinator does not start.
RunResult run_farm(const Options& opt, const TileBank& bank, const fs::path& base, int n, const std::string& webhook = {}) {
  const fs::path dir = base / ("n" + std::to_string(n));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::vector<tessera::worker::ChildProcess> children;
  std::vector<std::string> serve = {
      opt.tessera.string(), "serve", "--listen", "127.0.0.1:0", "--data", (dir / "data").string(), "--ready-file",
      (dir / "ready").string(), "--heartbeat-seconds", std::to_string(opt.heartbeat_seconds), "--max-connections",
      std::to_string(std::max(1024, n + 64)),  // one connection per simulated worker, the feeder's, and spare
      "--max-registrations-per-minute", std::to_string(60 * std::max(600, n))};  // every worker registers at once
  // A shared farm: two users and the workers' user, in a users file as `tessera users add` writes it.
  std::string tokens[3];
  if (opt.share) {
    json users = json::array();
    const char* names[3] = {"ana", "ben", "farm"};
    const char* roles[3] = {"user", "user", "worker"};
    std::mt19937_64 rng(std::random_device{}());
    for (int i = 0; i < 3; ++i) {
      char hex[49];
      std::snprintf(hex, sizeof hex, "%016llx%016llx%016llx", static_cast<unsigned long long>(rng()),
                    static_cast<unsigned long long>(rng()), static_cast<unsigned long long>(rng()));
      tokens[i] = hex;
      users.push_back({{"name", names[i]}, {"role", roles[i]}, {"token_sha256", tessera::sha256_hex(tokens[i])}});
    }
    std::ofstream(dir / "users.json") << json{{"users", users}}.dump();
    serve.insert(serve.end(), {"--users", (dir / "users.json").string()});
  }
  if (!webhook.empty()) serve.insert(serve.end(), {"--webhook", webhook});
  children.push_back(tessera::worker::spawn_child(serve, "coordinator", dir / "serve.log"));
  const std::string hostport = wait_ready(dir / "ready", children[0]);
  if (hostport.empty()) {
    tessera::worker::stop_children(children, 2s);
    throw std::runtime_error("the coordinator did not start: " + tessera::worker::tail_of_file(dir / "serve.log", 10));
  }

  Farm farm{opt, bank, tessera::client::parse_http_url("http://" + hostport)};
  {
    asio::io_context ioc;
    farm.endpoints = asio::ip::tcp::resolver(ioc).resolve(farm.url.host, farm.url.port);
  }
  farm.workers = n;
  farm.big_token = tokens[0];
  farm.small_token = tokens[1];
  farm.worker_token = tokens[2];
  const auto start = Clock::now();
  farm.window_start = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(opt.warmup));
  farm.window_end = farm.window_start +
                    std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(opt.seconds));
  std::vector<WorkerTally> tallies(size_t(n) + 2);
  std::vector<std::thread> threads;
  threads.emplace_back(opt.share ? share_feeder : feeder, std::ref(farm), std::ref(tallies[size_t(n)]));
  std::atomic<int64_t> events{0};
  if (opt.hanging_webhooks > 0)
    threads.emplace_back(job_events, std::ref(farm), std::ref(tallies[size_t(n) + 1]), opt.hanging_webhooks + 20,
                         std::ref(events));
  // The simulated workers, dealt round-robin to the event loops; each loop's thread runs until its workers return.
  std::deque<Loop> loops(size_t(std::max(1, std::min(opt.loop_threads, n))));
  for (int i = 0; i < n; ++i) {
    Loop& loop = loops[size_t(i) % loops.size()];
    WorkerTally& tally = tallies[size_t(i)];
    asio::co_spawn(loop.ioc, simulated_worker(farm, i, tally, loop.naps.emplace_back(loop.ioc)),
                   [&tally](const std::exception_ptr& e) {
                     if (!e) return;
                     ++tally.errors;
                     try {
                       std::rethrow_exception(e);
                     } catch (const std::exception& x) {
                       if (tally.first_error.empty()) tally.first_error = x.what();
                     }
                   });
  }
  for (Loop& loop : loops) loop.thread = std::thread([&loop] { loop.ioc.run(); });

  const auto metrics = [&farm] {  // empty when the coordinator does not answer
    try {
      HttpClient http(farm.url);
      const HttpResponse r = http.send("GET", routes::metrics());
      return r.status == 200 ? r.body : std::string();
    } catch (const std::exception&) {
      return std::string();
    }
  };
  RunResult result;
  std::this_thread::sleep_until(farm.window_start);
  const double serve_cpu0 = process_cpu_seconds(children[0].pid), self_cpu0 = self_cpu_seconds();
  result.metrics_start = metrics();
  std::this_thread::sleep_until(farm.window_end);
  const double serve_cpu1 = process_cpu_seconds(children[0].pid), self_cpu1 = self_cpu_seconds();
  result.metrics_end = metrics();
  if (opt.hanging_webhooks > 0) {  // how many deliveries the coordinator has, and how many are still pending
    try {
      HttpClient http(farm.url);
      const HttpResponse r = http.send("GET", routes::webhook_deliveries());
      if (r.status != 200) throw std::runtime_error("answered " + r.error_text());
      for (const protocol::WebhookDelivery& d :
           protocol::parse_answer<protocol::WebhookDeliveryList>(r.body, "delivery list").deliveries) {
        ++result.deliveries;
        if (d.state == "pending") ++result.pending_deliveries;
      }
    } catch (const std::exception& e) {
      ++tallies[size_t(n) + 1].errors;
      tallies[size_t(n) + 1].first_error = std::string("deliveries: ") + e.what();
    }
  }
  stop_farm(farm);
  for (Loop& loop : loops)
    asio::post(loop.ioc, [&loop] {
      for (asio::steady_timer& t : loop.naps) t.cancel();
    });
  for (std::thread& t : threads) t.join();
  for (Loop& loop : loops) loop.thread.join();
  tessera::worker::stop_children(children, 10s);

  result.job_events = events.load();
  result.workers = n;
  result.window_seconds = opt.seconds;
  result.coordinator_cpu_seconds = serve_cpu1 - serve_cpu0;
  result.client_cpu_seconds = self_cpu1 - self_cpu0;
  for (WorkerTally& t : tallies) {
    for (int r = 0; r < kRouteCount; ++r) {
      result.total.latency_ms[r].insert(result.total.latency_ms[r].end(), t.latency_ms[r].begin(), t.latency_ms[r].end());
    }
    result.total.lag_ms.insert(result.total.lag_ms.end(), t.lag_ms.begin(), t.lag_ms.end());
    result.total.tiles_accepted += t.tiles_accepted;
    result.total.upload_bytes += t.upload_bytes;
    result.total.errors += t.errors;
    result.total.spans.insert(result.total.spans.end(), t.spans.begin(), t.spans.end());
    if (result.total.first_error.empty()) result.total.first_error = t.first_error;
  }
  for (const auto& [id, j] : farm.jobs) result.jobs[id] = {j.owner, j.submitted};
  result.window_start = farm.window_start;
  result.window_end = farm.window_end;
  fs::remove_all(dir);
  return result;
}

/// The value of sample `name` (with its labels, e.g. `x_bucket{le="0.05"}`) in a Prometheus exposition; 0 when absent.
double sample(const std::string& text, const std::string& name) {
  const size_t at = text.find("\n" + name + " ");
  return at == std::string::npos ? 0.0 : std::strtod(text.c_str() + at + name.size() + 2, nullptr);
}

/// The store's disk costs within the window, from the coordinator's /metrics at its start and end: pages written to
/// the database's log per accepted tile, flushes a second and the share of them over 25, 50 and 100 ms. Empty for a
/// coordinator without a store on the disk.
std::string store_costs(const RunResult& r) {
  const std::string flush = "tessera_store_flush_duration_seconds";
  const auto delta = [&](const std::string& name) {
    return sample(r.metrics_end, name) - sample(r.metrics_start, name);
  };
  const double flushes = delta(flush + "_count");
  if (r.metrics_end.find(flush) == std::string::npos || flushes <= 0) return {};
  const auto over = [&](const char* bound) {
    return 100 * (flushes - delta(flush + "_bucket{le=\"" + bound + "\"}")) / flushes;
  };
  const double tiles = double(std::max<int64_t>(1, r.total.tiles_accepted));
  char line[256];
  std::snprintf(line, sizeof line,
                "store: %.2f log pages per tile, %.0f flushes a second, of them %.2f%% over 25 ms, %.2f%% over 50 ms, "
                "%.2f%% over 100 ms",
                delta("tessera_store_log_pages_total") / tiles, flushes / r.window_seconds, over("0.025"), over("0.05"),
                over("0.1"));
  return line;
}

/// The q-quantile (0..1) of values (sorted in place); 0 for none.
double quantile(std::vector<float>& values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const size_t i = std::min(values.size() - 1, size_t(q * double(values.size() - 1) + 0.5));
  return values[i];
}

/// A shared farm's figures: each user's part of the worker time while the small user has work (from each small job's
/// submission to its last tile's upload, within the window), also without each small job's first lease round (the
/// tiles already leased when it arrives finish first), and each small job's time to its first tile.
void report_share(const Options& opt, const RunResult& r) {
  struct Small {
    Clock::time_point submitted, first = Clock::time_point::max(), last = Clock::time_point::min();
    int tiles = 0;
  };
  std::map<std::string, Small> small;
  for (const auto& [id, job] : r.jobs)
    if (job.first == "small") small[id].submitted = job.second;
  for (const WorkerTally::Span& sp : r.total.spans) {
    const auto it = small.find(sp.job);
    if (it == small.end()) continue;
    it->second.first = std::min(it->second.first, sp.granted);
    it->second.last = std::max(it->second.last, sp.done);
    ++it->second.tiles;
  }
  const auto round = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.2 * opt.tile_seconds));
  double whole[2] = {0, 0}, steady[2] = {0, 0};  // worker-seconds of the big and the small user
  const auto overlap = [](Clock::time_point a0, Clock::time_point a1, Clock::time_point b0, Clock::time_point b1) {
    return std::max(0.0, std::chrono::duration<double>(std::min(a1, b1) - std::max(a0, b0)).count());
  };
  std::vector<double> first_tile;
  int submitted = 0, finished = 0;
  for (const auto& [id, sm] : small) {
    if (sm.submitted >= r.window_end) continue;
    ++submitted;
    const bool done = sm.tiles >= opt.small_tiles;
    finished += done;
    const Clock::time_point end = std::min(done ? sm.last : r.window_end, r.window_end);
    if (sm.first != Clock::time_point::max())
      first_tile.push_back(std::chrono::duration<double>(sm.first - sm.submitted).count());
    for (const WorkerTally::Span& sp : r.total.spans) {
      const auto job = r.jobs.find(sp.job);
      const int who = job != r.jobs.end() && job->second.first == "small" ? 1 : 0;
      whole[who] += overlap(sp.granted, sp.done, std::max(sm.submitted, r.window_start), end);
      steady[who] += overlap(sp.granted, sp.done, std::max(sm.submitted + round, r.window_start), end);
    }
  }
  std::sort(first_tile.begin(), first_tile.end());
  const auto pct = [](const double (&w)[2], int who) { return w[0] + w[1] > 0 ? 100 * w[who] / (w[0] + w[1]) : 0.0; };
  std::printf("  %s: %d small jobs submitted in the window, %zu given a first tile and %d finished in it\n",
              opt.one_user ? "one user (strict priority, then age)" : "two users, equal weights", submitted,
              first_tile.size(), finished);
  std::printf("  worker time while the small jobs' user has work: big %.1f%%, small %.1f%% (%.0f worker-s); without "
              "each small job's first lease round: big %.1f%%, small %.1f%%\n",
              pct(whole, 0), pct(whole, 1), whole[0] + whole[1], pct(steady, 0), pct(steady, 1));
  if (!first_tile.empty())
    std::printf("  time to a small job's first tile: median %.2f s, max %.2f s (%.2f lease rounds of %.2f s)%s\n",
                first_tile[first_tile.size() / 2], first_tile.back(), first_tile.back() / opt.tile_seconds,
                opt.tile_seconds, int(first_tile.size()) < submitted ? "; the others none within the window" : "");
  else if (submitted)
    std::printf("  time to a small job's first tile: none was given a tile within the window\n");
}

}  // namespace

/// The A/B run of --hanging-webhooks: the first farm size four times, A B A B (the machine's other load falls on both
/// variants alike), then each variant's tiles/s and the p99 of its lease and upload requests together (with one
/// request per tile the next lease comes with the upload) over its runs, and B / A.
void run_hanging_webhooks(const Options& opt, const TileBank& bank, const fs::path& base) {
  const int n = opt.worker_counts.front();
  HangingReceiver receiver;
  std::printf("A: no webhooks; B: serve --webhook %s, a receiver that accepts connections and never answers "
              "(the sender's default timeout and threads). Both: %d jobs submitted and cancelled at the start, then "
              "4 a second (a delivery each in B).\n",
              receiver.url().c_str(), opt.hanging_webhooks + 20);
  std::printf("%5s %3s %9s %10s %10s %10s %10s %12s %9s %9s %7s %9s\n", "run", "", "tiles/s", "lease p50",
              "lease p99", "upld p99", "coord CPU", "job events", "delivs", "pending", "errors", "lag p99");
  struct Variant {
    const char* name;
    std::string webhook;
    int64_t tiles = 0;
    double seconds = 0;
    std::vector<float> request_ms{};  // lease and upload requests
    int64_t min_pending = INT64_MAX;
  };
  Variant variants[2] = {{"A", {}}, {"B", receiver.url()}};
  for (int round = 0; round < 4; ++round) {
    Variant& v = variants[round % 2];
    RunResult r = run_farm(opt, bank, base, n, v.webhook);
    std::vector<float>& lease = r.total.latency_ms[kLease];
    std::printf("%5d %3s %9.1f %10.2f %10.2f %10.2f %9.1f%% %12lld %9lld %9lld %7lld %9.2f\n", round + 1, v.name,
                double(r.total.tiles_accepted) / r.window_seconds, quantile(lease, 0.5), quantile(lease, 0.99),
                quantile(r.total.latency_ms[kUpload], 0.99), 100 * r.coordinator_cpu_seconds / r.window_seconds,
                static_cast<long long>(r.job_events), static_cast<long long>(r.deliveries),
                static_cast<long long>(r.pending_deliveries), static_cast<long long>(r.total.errors),
                quantile(r.total.lag_ms, 0.99));
    if (!r.total.first_error.empty()) std::printf("      first error: %s\n", r.total.first_error.c_str());
    std::fflush(stdout);
    v.tiles += r.total.tiles_accepted;
    v.seconds += r.window_seconds;
    v.request_ms.insert(v.request_ms.end(), lease.begin(), lease.end());
    const std::vector<float>& upload = r.total.latency_ms[kUpload];
    v.request_ms.insert(v.request_ms.end(), upload.begin(), upload.end());
    v.min_pending = std::min(v.min_pending, r.pending_deliveries);
  }
  const Variant& a = variants[0];
  const Variant& b = variants[1];
  std::vector<float> la = a.request_ms, lb = b.request_ms;
  const double rate_a = double(a.tiles) / a.seconds, rate_b = double(b.tiles) / b.seconds;
  const double p99_a = quantile(la, 0.99), p99_b = quantile(lb, 0.99);
  std::printf("\nA (no webhooks):             %8.1f tiles/s, lease and upload requests p50 %.2f ms, p99 %.2f ms\n", rate_a,
              quantile(la, 0.5), p99_a);
  std::printf("B (deliveries hanging):      %8.1f tiles/s, lease and upload requests p50 %.2f ms, p99 %.2f ms; at least %lld deliveries "
              "pending at the end of each window, %lld connections accepted by the receiver\n",
              rate_b, quantile(lb, 0.5), p99_b, static_cast<long long>(b.min_pending),
              static_cast<long long>(receiver.accepted()));
  std::printf("B / A: tiles/s %.3f, request p99 %.2f\n", rate_a > 0 ? rate_b / rate_a : 0.0, p99_a > 0 ? p99_b / p99_a : 0.0);
  if (b.min_pending < opt.hanging_webhooks)
    std::printf("NOTE: fewer than %d deliveries were pending in a B window\n", opt.hanging_webhooks);
}

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{"N simulated workers against a real tessera serve: coordinator CPU, latency and tile rate"};
  app.add_option("--tessera", opt.tessera, "The tessera binary")->required()->check(CLI::ExistingFile);
  app.add_option("--workers", opt.worker_counts, "Simulated farm sizes")->delimiter(',');
  app.add_option("--seconds", opt.seconds, "Measured window per farm size")->check(CLI::Range(1.0, 3600.0));
  app.add_option("--warmup", opt.warmup, "Unmeasured seconds before each window")->check(CLI::Range(0.0, 600.0));
  app.add_option("--tile-seconds", opt.tile_seconds, "Simulated render time per tile")->check(CLI::Range(0.01, 600.0));
  app.add_option("--heartbeat-seconds", opt.heartbeat_seconds, "Heartbeat period (coordinator flag)")
      ->check(CLI::Range(1, 3600));
  app.add_option("--image", opt.image, "Job image edge in pixels")->check(CLI::Range(16, 16384));
  app.add_option("--tile", opt.tile, "Tile edge in pixels")->check(CLI::Range(8, 4096));
  app.add_option("--data-dir", opt.data_dir, "Folder for the coordinators' data (default: a temporary folder)");
  app.add_flag("--share", opt.share,
               "Two users share the farm: one big job and a small job every --small-every seconds (users file)");
  app.add_flag("--one-user", opt.one_user, "With --share: submit both users' jobs as one user (strict priority)");
  app.add_option("--small-every", opt.small_every, "With --share: seconds between small jobs")
      ->check(CLI::Range(1.0, 3600.0));
  app.add_option("--small-tiles", opt.small_tiles, "With --share: tiles of a small job")->check(CLI::Range(1, 4096));
  app.add_option("--big-tiles-edge", opt.big_tiles_edge, "With --share: the big job is this many tiles square")
      ->check(CLI::Range(1, 1000));
  app.add_option("--hanging-webhooks", opt.hanging_webhooks,
                 "A B A B at the first --workers count: without webhooks, and with this many deliveries or more "
                 "pending to a receiver that never answers")
      ->check(CLI::Range(1, 100000));
  app.add_option("--loop-threads", opt.loop_threads,
                 "Event-loop threads driving the simulated workers (each a keep-alive connection on one of them)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--two-requests", opt.two_requests,
               "Uploads do not ask for the next lease: every lease is a lease request of its own (as workers did "
               "before uploads carried the next lease)");
  app.add_flag("--spec-by-get", opt.spec_by_get,
               "Ask for bare leases and GET each job's spec (as workers did before specs came with leases)");
  CLI11_PARSE(app, argc, argv);

  try {
    fs::path base = opt.data_dir;
    if (base.empty()) base = fs::temp_directory_path() / ("tessera-sim-workers-" + std::to_string(getpid()));
    fs::create_directories(base);
    TileBank bank;
    if (opt.share) {
      bank.add(opt.big_tiles_edge * opt.tile, opt.big_tiles_edge * opt.tile, opt.tile);
      bank.add(opt.small_tiles * opt.tile, opt.tile, opt.tile);
      opt.image = opt.big_tiles_edge * opt.tile;  // for the line below
    } else {
      bank.add(opt.image, opt.image, opt.tile);
    }
    if (opt.hanging_webhooks > 0) bank.add(opt.tile, opt.tile, opt.tile);  // the job events' one-tile jobs
    const int first = std::min(opt.tile, opt.image);
    const std::string tile_bytes = std::to_string(bank.at(opt.image, opt.image, {0, 0, first, first}).size());

    std::printf("sim_workers: %d-pixel jobs in %d-pixel tiles (upload %s bytes each, uncompressed float32), "
                "tile time %.2f s +-20%%, heartbeat every %d s, window %.0f s after %.0f s warm-up, %u cores, %s, %s, "
                "workers on %d event-loop thread%s\n",
                opt.image, opt.tile, tile_bytes.c_str(), opt.tile_seconds, opt.heartbeat_seconds, opt.seconds,
                opt.warmup, std::thread::hardware_concurrency(),
                opt.spec_by_get ? "specs by GET" : "specs with the leases",
                opt.two_requests ? "a lease request per tile (--two-requests)" : "the next lease asked with each upload",
                opt.loop_threads,
                opt.loop_threads == 1 ? "" : "s");
    {
      std::ifstream load("/proc/loadavg");
      std::string l1, l5, l15;
      load >> l1 >> l5 >> l15;
      std::printf("load average before the run: %s %s %s (other processes share these cores)\n", l1.c_str(),
                  l5.c_str(), l15.c_str());
    }
    if (opt.hanging_webhooks > 0) {
      run_hanging_webhooks(opt, bank, base);
      fs::remove_all(base);
      return 0;
    }
    std::printf("%6s %9s %9s %10s %10s %9s %9s %9s %9s %9s %7s %9s %9s\n", "N", "tiles/s", "ideal/s", "coord CPU",
                "ms/tile", "client", "lease p50", "lease p99", "upld p50", "upld p99", "errors", "client/t", "lag p99");
    std::vector<RunResult> results;
    for (int n : opt.worker_counts) {
      RunResult r = run_farm(opt, bank, base, n);
      const double tiles_per_s = double(r.total.tiles_accepted) / r.window_seconds;
      const double ideal = double(n) / opt.tile_seconds;
      const auto per_tile = [&](double cpu_seconds) {
        return r.total.tiles_accepted ? 1000 * cpu_seconds / double(r.total.tiles_accepted) : 0.0;
      };
      std::printf("%6d %9.1f %9.1f %9.1f%% %10.3f %8.1f%% %9.2f %9.2f %9.2f %9.2f %7lld %9.3f %9.2f\n", n, tiles_per_s,
                  ideal, 100 * r.coordinator_cpu_seconds / r.window_seconds, per_tile(r.coordinator_cpu_seconds),
                  100 * r.client_cpu_seconds / r.window_seconds, quantile(r.total.latency_ms[kLease], 0.5),
                  quantile(r.total.latency_ms[kLease], 0.99), quantile(r.total.latency_ms[kUpload], 0.5),
                  quantile(r.total.latency_ms[kUpload], 0.99), static_cast<long long>(r.total.errors),
                  per_tile(r.client_cpu_seconds), quantile(r.total.lag_ms, 0.99));
      if (opt.share) report_share(opt, r);
      std::fflush(stdout);
      results.push_back(std::move(r));
    }
    std::printf("\nPer-route latency in the window (ms: count, p50, p99, max):\n");
    for (RunResult& r : results) {
      std::printf("N=%d:", r.workers);
      for (int k = 0; k < kRouteCount; ++k) {
        std::vector<float>& v = r.total.latency_ms[k];
        if (v.empty()) continue;
        std::printf("  %s %zu/%.2f/%.2f/%.1f", kRouteNames[k], v.size(), quantile(v, 0.5), quantile(v, 0.99),
                    double(*std::max_element(v.begin(), v.end())));
      }
      if (!r.total.lag_ms.empty())
        std::printf("  (loop lag %zu/%.2f/%.2f/%.1f)", r.total.lag_ms.size(), quantile(r.total.lag_ms, 0.5),
                    quantile(r.total.lag_ms, 0.99), double(*std::max_element(r.total.lag_ms.begin(), r.total.lag_ms.end())));
      std::printf("\n");
      if (const std::string costs = store_costs(r); !costs.empty()) std::printf("  %s\n", costs.c_str());
      if (!r.total.first_error.empty()) std::printf("  first error: %s\n", r.total.first_error.c_str());
    }
    std::printf("\ncoord CPU: utime+stime of `tessera serve` / window (100%% = one core); ms/tile: coordinator CPU per "
                "accepted tile, all its requests included; client: this process's CPU / window; client/t: its ms CPU per "
                "accepted tile; lag p99: how late the event loops ran the workers' naps after their due time (ms; a "
                "loop that lags also delays reading answers, so latencies near it are the simulator's, not the "
                "coordinator's); latencies: request's first byte written to answer's last byte read; ideal/s: N / "
                "tile time (what the farm would do with no overhead and no 204 waits).\n");
    fs::remove_all(base);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sim_workers: %s\n", e.what());
    return 1;
  }
  return 0;
}
