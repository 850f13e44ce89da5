// Purging jobs: the scheduler forgets an ended job in memory and in the store in one change, the database
// file gives the pages back, a sweep purges jobs past their retention time and blobs no job references are collected
// after their grace period; listings filter by state and page with a cursor.
#include "server/collector.h"
#include "server/database.h"
#include "server/event_bus.h"
#include "server/farm_events.h"
#include "server/job_service.h"

#include "core/util/sha256.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

int64_t wall_now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A data folder with a scheduler over a DurableStore, its job service and collector, on a manual clock that starts at
// the wall time (blob ages come from file times).
struct PurgeTest : ::testing::Test {
  fs::path dir = fs::temp_directory_path() / ("tessera-purge-test-" + random_hex(6));
  int64_t now = wall_now_ms();
  ClockMs clock = [this] { return now; };
  std::unique_ptr<DurableStore> store;
  std::unique_ptr<DiskBlobStore> blobs;
  std::unique_ptr<Scheduler> sched;
  Metrics metrics;
  EventBus bus{EventBusOptions{}, "purge"};
  FarmEvents events{bus};
  std::unique_ptr<DiskSpace> disk;
  std::unique_ptr<JobService> service;
  std::unique_ptr<Collector> collector;
  RetentionOptions retention{std::optional<int64_t>(3'600'000), 60'000};

  void SetUp() override { open(); }
  void TearDown() override {
    collector.reset();
    service.reset();
    sched.reset();
    store.reset();
    blobs.reset();
    fs::remove_all(dir);
  }
  void open() {
    store = std::make_unique<DurableStore>(dir);
    blobs = std::make_unique<DiskBlobStore>(dir / "blobs");
    sched = std::make_unique<Scheduler>(SchedulerConfig{10'000, 3, 2, "p"}, clock, *store);
    disk = std::make_unique<DiskSpace>(dir, 0);
    service = std::make_unique<JobService>(*sched, *blobs, *store, metrics, clock, AdmissionLimits{}, events, *disk);
    collector = std::make_unique<Collector>(*service, *sched, *blobs, clock, retention);
  }
  void reopen() {
    collector.reset();
    service.reset();
    sched.reset();
    store.reset();
    blobs.reset();
    open();
  }
  // A job of `w` x 64 pixels in 64-pixel tiles whose spec names `assets`.
  std::string job(int w = 128, std::map<std::string, std::string> assets = {}) {
    JobParams p;
    p.name = "n";
    p.width = w;
    p.height = 64;
    p.tile_size = 64;
    p.spp = 4;
    p.scene_hash = "h";
    const std::string id = sched->new_job_id();
    protocol::JobSpec spec;
    spec.assets = std::move(assets);
    spec.width = p.width;
    spec.height = p.height;
    spec.tile_size = p.tile_size;
    spec.sampling.spp = p.spp;
    store->save_record(id, spec);
    return sched->add_job(p, id);
  }
  // Renders every tile of every queued job with big, incompressible pixels and marks the jobs done.
  void render_all(const std::string& worker) {
    while (true) {
      const AcquireResult r = sched->acquire(worker);
      if (r.status != AcquireResult::granted) break;
      ASSERT_EQ(sched->claim_result(r.lease.id).status, ResultClaim::proceed);
      Image img = Image::make(r.lease.window.width(), r.lease.window.height());
      for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i % 977) * 0.37f + float(r.lease.tile);
      if (sched->finish_result(r.lease.id, 1, tile_bytes(img)).last) sched->complete_job(r.lease.job);
    }
  }
  std::string put_blob(const std::string& bytes) {
    const std::string sha = sha256_hex(bytes);
    EXPECT_EQ(blobs->put(sha, bytes).status, PutBlobResult::created);
    return sha;
  }
  static uint64_t file_bytes(const fs::path& p) {
    std::error_code ec;
    const uint64_t n = fs::file_size(p, ec);
    return ec ? 0 : n;
  }
  // The database, its log and the pixel files.
  uint64_t stored_bytes() const {
    uint64_t pixels = 0;
    for (const auto& f : fs::directory_iterator(dir / DurableStore::kPixelsDir)) pixels += file_bytes(f.path());
    return file_bytes(dir / "tessera.db") + file_bytes(fs::path(dir / "tessera.db").string() + "-wal") + pixels;
  }
};

TEST_F(PurgeTest, OnlyEndedJobsArePurgedAndTheirLeasesBecomeUnknown) {
  const std::string running = job();
  const std::string w = sched->register_worker("w").id;
  const AcquireResult l = sched->acquire(w);
  ASSERT_EQ(l.status, AcquireResult::granted);
  EXPECT_EQ(sched->purge(running).status, PurgeResult::not_ended);
  EXPECT_EQ(sched->purge("j-none").status, PurgeResult::unknown);
  ASSERT_EQ(sched->pause(running).status, PauseResult::changed);
  EXPECT_EQ(sched->purge(running).status, PurgeResult::not_ended);
  ASSERT_EQ(sched->resume(running).status, PauseResult::changed);

  // A tile claimed before the job was cancelled is still being stored: the purge waits for it.
  ASSERT_EQ(sched->claim_result(l.lease.id).status, ResultClaim::proceed);
  ASSERT_EQ(sched->cancel(running).status, CancelResult::cancelled);
  const PurgeResult busy = sched->purge(running);
  EXPECT_EQ(busy.status, PurgeResult::busy);
  EXPECT_EQ(busy.was, JobState::cancelled);
  sched->abandon_result(l.lease.id);

  const PurgeResult r = sched->purge(running);
  EXPECT_EQ(r.status, PurgeResult::purged);
  EXPECT_EQ(r.was, JobState::cancelled);
  EXPECT_FALSE(sched->job(running));
  EXPECT_EQ(sched->heartbeat(l.lease.id).status, HeartbeatResult::unknown);  // 404, not a resurrected row
  EXPECT_EQ(sched->check_result(l.lease.id).status, ResultClaim::unknown);
  EXPECT_EQ(sched->claim_result(l.lease.id).status, ResultClaim::unknown);
  EXPECT_EQ(sched->fail(l.lease.id, "late").status, FailResult::unknown);
  EXPECT_FALSE(sched->release(l.lease.id));
  EXPECT_EQ(sched->purge(running).status, PurgeResult::unknown);
  EXPECT_TRUE(sched->jobs().empty());
  EXPECT_FALSE(sched->workers().at(0).job);

  reopen();  // forgotten in the store too, spec included
  EXPECT_FALSE(sched->job(running));
  EXPECT_FALSE(store->load_record(running));
  EXPECT_EQ(sched->heartbeat(l.lease.id).status, HeartbeatResult::unknown);
}

TEST_F(PurgeTest, PurgingGivesTheSpaceBackAndLeavesOtherJobsWhole) {
  const uint64_t empty = stored_bytes();
  const std::string keep = job(128);
  const std::string w = sched->register_worker("w").id;
  render_all(w);
  std::vector<std::string> doomed;
  for (int i = 0; i < 4; ++i) doomed.push_back(job(512));
  render_all(w);
  const auto kept_pixels = store->tile_pixels(keep);
  const uint64_t full = stored_bytes();
  for (const std::string& j : doomed) {
    ASSERT_EQ(sched->job(j)->state, JobState::done);
    ASSERT_EQ(service->purge(j), JobState::done);
  }
  store->sync();  // a pixel file goes once the purge is on the disk
  for (const std::string& j : doomed) EXPECT_FALSE(fs::exists(dir / DurableStore::kPixelsDir / (j + ".pixels")));
  const uint64_t after = stored_bytes();
  std::printf("database + log + pixel files: empty %llu bytes, 5 jobs %llu bytes, 4 of them purged %llu bytes\n",
              static_cast<unsigned long long>(empty), static_cast<unsigned long long>(full),
              static_cast<unsigned long long>(after));
  // 4 jobs of 8 tiles of 64x64 float RGB are 1.5 MiB of pixels: their files go, the database and its log give back
  // their rows.
  EXPECT_GT(full, empty + 1'500'000);
  EXPECT_LT(after, empty + 200'000);
  reopen();
  EXPECT_EQ(store->tile_pixels(keep), kept_pixels);
  EXPECT_EQ(sched->job(keep)->state, JobState::done);
  for (const std::string& j : doomed) EXPECT_TRUE(store->tile_pixels(j).empty());
}

// A database made by a build before purging existed has auto_vacuum off: opening it switches it on (one VACUUM) and
// keeps everything in it.
TEST_F(PurgeTest, AnOlderDatabaseIsSwitchedToIncrementalVacuumOnOpen) {
  const std::string j = job();
  collector.reset();
  service.reset();
  sched.reset();
  store.reset();
  const auto auto_vacuum = [&] {
    Database db(dir / "tessera.db");
    Statement& st = db.statement("PRAGMA auto_vacuum");
    return st.step() ? st.integer(0) : -1;
  };
  {
    Database db(dir / "tessera.db");
    db.exec("PRAGMA auto_vacuum=NONE");
    db.exec("VACUUM");
  }
  ASSERT_EQ(auto_vacuum(), 0);
  open();
  EXPECT_EQ(auto_vacuum(), 2);  // INCREMENTAL
  EXPECT_EQ(sched->job(j)->state, JobState::queued);
  EXPECT_TRUE(store->load_record(j));
}

TEST_F(PurgeTest, ServiceRefusesWithASentenceAndDeletesTheResultFile) {
  const std::string j = job();
  try {
    service->purge(j);
    FAIL() << "a queued job was purged";
  } catch (const protocol::ApiError& e) {
    EXPECT_EQ(e.status, 409);
    EXPECT_NE(std::string(e.what()).find("only done, failed or cancelled jobs can be purged"), std::string::npos);
  }
  try {
    service->purge("j-nope");
    FAIL() << "an unknown job was purged";
  } catch (const protocol::ApiError& e) {
    EXPECT_EQ(e.status, 404);
  }
  const std::string w = sched->register_worker("w").id;
  render_all(w);
  const fs::path result = store->result_path(j);
  { std::ofstream(result) << "exr"; }
  EXPECT_EQ(service->purge(j), JobState::done);
  EXPECT_FALSE(fs::exists(result.parent_path()));

  // A result file whose job's rows were purged before a crash is deleted at the next start.
  const std::string k = job();
  render_all(w);
  { std::ofstream(store->result_path(k)) << "exr"; }
  ASSERT_EQ(sched->purge(k).status, PurgeResult::purged);
  reopen();
  service->recover();
  EXPECT_FALSE(fs::exists(dir / "jobs" / k));
}

TEST_F(PurgeTest, SweepPurgesJobsPastTheirRetentionTimeOnly) {
  const std::string w = sched->register_worker("w").id;
  const std::string old_done = job();
  render_all(w);
  const std::string old_cancelled = job();
  ASSERT_EQ(sched->cancel(old_cancelled).status, CancelResult::cancelled);
  now += 30 * 60'000;
  const std::string young = job();
  render_all(w);
  const std::string queued = job();
  now += 31 * 60'000;  // the first two ended 61 min ago, `young` 31 min ago
  const SweepReport r = collector->sweep();
  EXPECT_EQ(std::set<std::string>(r.purged_jobs.begin(), r.purged_jobs.end()),
            (std::set<std::string>{old_done, old_cancelled}));
  EXPECT_TRUE(sched->job(young));
  EXPECT_TRUE(sched->job(queued));
  now += 10 * 3'600'000;  // a queued job is never purged, however old
  EXPECT_EQ(collector->sweep().purged_jobs, std::vector<std::string>{young});
  EXPECT_TRUE(sched->job(queued));
}

TEST_F(PurgeTest, NoRetentionKeepsFinishedJobsForever) {
  retention.retain_finished_ms.reset();
  reopen();
  const std::string w = sched->register_worker("w").id;
  const std::string j = job();
  render_all(w);
  now += int64_t(1000) * 24 * 3'600'000;
  EXPECT_TRUE(collector->sweep().purged_jobs.empty());
  EXPECT_TRUE(sched->job(j));
}

TEST_F(PurgeTest, BlobsGoWhenNoJobNamesThemAndTheirGracePeriodIsOver) {
  const std::string used = put_blob("mesh of a kept job");
  const std::string shared = put_blob("texture of both jobs");
  const std::string only_purged = put_blob("texture of the purged job");
  const std::string fresh = put_blob("checked by a client for a submission in progress");
  const std::string orphan = put_blob("uploaded long ago, never submitted");
  // Every blob was stored two minutes ago (the grace period is one minute) ...
  for (const std::string& sha : {used, shared, only_purged, fresh, orphan})
    fs::last_write_time(*blobs->file(sha), fs::file_time_type::clock::now() - std::chrono::minutes(2));
  // ... but a client checked (HEAD) or uploaded `fresh` again just now, before submitting the job that names it.
  ASSERT_TRUE(blobs->touch(fresh));
  const std::string kept = job(128, {{"a.obj", used}, {"t.png", shared}});
  const std::string purged = job(128, {{"t.png", shared}, {"u.png", only_purged}});
  const std::string w = sched->register_worker("w").id;
  render_all(w);

  EXPECT_EQ(collector->collect_blobs(), 1u);
  EXPECT_FALSE(blobs->has(orphan));
  EXPECT_TRUE(blobs->has(fresh));
  EXPECT_TRUE(blobs->has(only_purged));

  EXPECT_EQ(collector->purge(purged), JobState::done);  // a purge collects what only that job named
  EXPECT_FALSE(blobs->has(only_purged));
  EXPECT_TRUE(blobs->has(shared));
  EXPECT_TRUE(blobs->has(used));
  EXPECT_TRUE(blobs->has(fresh));

  now += 2 * 60'000;  // the submission never came: `fresh` goes once its grace period is over
  EXPECT_EQ(collector->sweep().blobs_removed, 1u);
  EXPECT_FALSE(blobs->has(fresh));
  EXPECT_TRUE(blobs->has(used));
  EXPECT_TRUE(sched->job(kept));
}

TEST_F(PurgeTest, ListingsFilterByStateAndPageNewestFirst) {
  const std::string w = sched->register_worker("w").id;
  std::vector<std::string> done;
  for (int i = 0; i < 3; ++i) {
    done.push_back(job());
    render_all(w);
  }
  const std::string cancelled = job();
  ASSERT_EQ(sched->cancel(cancelled).status, CancelResult::cancelled);
  const std::string queued1 = job(), queued2 = job();
  const auto ids = [](const protocol::JobList& l) {
    std::vector<std::string> v;
    for (const auto& s : l.jobs) v.push_back(s.id);
    return v;
  };
  protocol::JobListQuery q;
  EXPECT_EQ(ids(service->list(q)), (std::vector<std::string>{queued2, queued1, cancelled, done[2], done[1], done[0]}));
  EXPECT_FALSE(service->list(q).next);

  q.states = {JobState::done, JobState::cancelled};
  q.limit = 2;
  const protocol::JobList p1 = service->list(q);
  EXPECT_EQ(ids(p1), (std::vector<std::string>{cancelled, done[2]}));
  ASSERT_TRUE(p1.next);
  q.after = *p1.next;
  const protocol::JobList p2 = service->list(q);
  EXPECT_EQ(ids(p2), (std::vector<std::string>{done[1], done[0]}));
  EXPECT_FALSE(p2.next);

  // The cursor still works when the job it was taken at is purged; a job id works as a cursor too.
  ASSERT_EQ(service->purge(done[2]), JobState::done);
  EXPECT_EQ(ids(service->list(q)), (std::vector<std::string>{done[1], done[0]}));
  q.after = done[1];
  q.limit = 0;
  EXPECT_EQ(ids(service->list(q)), (std::vector<std::string>{done[0]}));
  q.after = "j-unknown";
  try {
    service->list(q);
    FAIL() << "an unknown cursor was accepted";
  } catch (const protocol::ApiError& e) {
    EXPECT_EQ(e.status, 400);
    EXPECT_NE(std::string(e.what()).find("neither"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace tessera::server
