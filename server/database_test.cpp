// The durable store: every piece of scheduler state survives closing and reopening the database, a tile is never
// done without its pixels, and a restarted scheduler resumes where the old one stopped.
#include "server/database.h"

#include "tests/support/test_files.h"
#include "server/assembly.h"
#include "server/coordinator.h"
#include "server/memory_store.h"
#include "server/worker_secret.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <set>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

// A data folder with a scheduler over a DurableStore on a manual clock; reopen() simulates a restart.
struct DatabaseTest : ::testing::Test {
  fs::path dir;
  int64_t now = 5'000'000;
  std::unique_ptr<DurableStore> store;
  std::unique_ptr<Scheduler> sched;

  void SetUp() override {
    dir = fs::temp_directory_path() / ("tessera-db-test-" + random_hex(6));
    open();
  }
  void TearDown() override {
    sched.reset();
    store.reset();
    fs::remove_all(dir);
  }
  void open(const std::string& tag = "a") {
    store = std::make_unique<DurableStore>(dir);
    sched = std::make_unique<Scheduler>(SchedulerConfig{10'000, 3, 2, tag}, [this] { return now; }, *store);
  }
  void reopen(const std::string& tag = "a") {
    sched.reset();
    store.reset();
    open(tag);
  }
  std::string job(int w = 128, int h = 64, int ts = 64, const std::string& name = "n") {
    JobParams p;
    p.name = name;
    p.priority = 3;
    p.width = w;
    p.height = h;
    p.tile_size = ts;
    p.spp = 7;
    p.seed = 0xfedcba9876543210ull;  // above INT64_MAX: stored as its bit pattern
    p.scene_hash = "hash";
    return sched->add_job(p);
  }
  Lease lease(const std::string& worker) {
    const AcquireResult r = sched->acquire(worker);
    EXPECT_EQ(r.status, AcquireResult::granted);
    return r.lease;
  }
  // A tile's pixels, distinct per tile.
  static Image pixels_for(const PixelWindow& w, float base) {
    Image img = Image::make(w.width(), w.height());
    for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = base + float(i) * 0.25f;
    return img;
  }
  void upload(const Lease& l, float base) {
    ASSERT_EQ(sched->claim_result(l.id).status, ResultClaim::proceed);
    sched->finish_result(l.id, 100, tile_bytes(pixels_for(l.window, base)));
  }
};

TEST_F(DatabaseTest, AJobsWorkersAreRowsOfTheirOwnAfterAListAnOlderBuildWrote) {
  const std::string j = job(192, 64, 64);  // 3 tiles
  const std::string wa = sched->register_worker("alpha").id, wb = sched->register_worker("beta").id;
  upload(lease(wa), 1.0f);
  reopen();
  {
    // An older build kept the whole list in the job's row; this one adds its workers after it.
    Database db(dir / "tessera.db");
    db.exec("DELETE FROM job_workers");
    db.exec("UPDATE jobs SET workers = '[\"w-old\", \"" + wa + "\"]' WHERE id = '" + j + "'");
  }
  reopen();
  EXPECT_EQ(sched->job(j)->workers, (std::vector<std::string>{"w-old", wa}));
  upload(lease(wb), 2.0f);
  upload(lease(wa), 3.0f);  // already listed: no second row
  reopen();
  EXPECT_EQ(sched->job(j)->workers, (std::vector<std::string>{"w-old", wa, wb}));
  Database db(dir / "tessera.db");
  Statement& rows = db.statement("SELECT count(*) FROM job_workers WHERE job = ?");
  rows.bind_text(1, j);
  ASSERT_TRUE(rows.step());
  EXPECT_EQ(rows.integer(0), 1) << "one row per worker added, none for those the old list had";
}

TEST_F(DatabaseTest, EveryPieceOfStateSurvivesAReopen) {
  const std::string j = job(192, 64, 64);  // 3 tiles
  const std::string other = job(64, 64, 64, "other");
  ASSERT_EQ(sched->cancel(other).status, CancelResult::cancelled);
  const std::string wa = sched->register_worker("alpha").id, wb = sched->register_worker("beta").id;
  const Lease l0 = lease(wa);
  upload(l0, 1.0f);
  const Lease l1 = lease(wb);
  ASSERT_EQ(sched->heartbeat(l1.id, 55).status, HeartbeatResult::ok);
  const Lease l2 = lease(wa);
  ASSERT_EQ(sched->fail(l2.id, "boom").status, FailResult::recorded);
  const JobStatus before = *sched->job(j);
  const JobStatus other_before = *sched->job(other);
  const SchedulerCounters cb = sched->counters();

  now += 60'000;  // far past every deadline: a restart must not expire the live lease
  reopen();
  const auto after = sched->job(j);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->params.name, "n");
  EXPECT_EQ(after->params.priority, 3);
  EXPECT_EQ(after->params.width, 192);
  EXPECT_EQ(after->params.spp, 7u);
  EXPECT_EQ(after->params.seed, 0xfedcba9876543210ull);
  EXPECT_EQ(after->params.scene_hash, "hash");
  EXPECT_EQ(after->state, JobState::running);
  EXPECT_EQ(after->created_ms, before.created_ms);
  EXPECT_EQ(after->started_ms, before.started_ms);
  EXPECT_EQ(after->rays, before.rays);
  EXPECT_EQ(after->rays, 155u);
  EXPECT_EQ(after->workers, before.workers);
  EXPECT_EQ(after->tiles.total, 3);
  EXPECT_EQ(after->tiles.done, 1);
  EXPECT_EQ(after->tiles.leased, 1);
  EXPECT_EQ(after->tiles.pending, 1);
  const auto ob = sched->job(other);
  ASSERT_TRUE(ob);
  EXPECT_EQ(ob->state, JobState::cancelled);
  EXPECT_EQ(ob->finished_ms, other_before.finished_ms);
  const SchedulerCounters ca = sched->counters();
  EXPECT_EQ(ca.tiles_rendered, cb.tiles_rendered);
  EXPECT_EQ(ca.rays, cb.rays);
  EXPECT_EQ(ca.workers, 2);
  EXPECT_EQ(ca.active_leases, 1);
  EXPECT_EQ(ca.jobs.at(JobState::running), 1);
  EXPECT_EQ(ca.jobs.at(JobState::cancelled), 1);

  // The live lease is still live, with a fresh deadline; the ended ones still answer as ended.
  const HeartbeatResult h = sched->heartbeat(l1.id);
  EXPECT_EQ(h.status, HeartbeatResult::ok);
  EXPECT_EQ(h.deadline_ms, now + 10'000);
  EXPECT_EQ(sched->heartbeat(l0.id).status, HeartbeatResult::gone);
  EXPECT_EQ(sched->check_result(l0.id).status, ResultClaim::duplicate);
  // The failure count survived: one more failure of alpha blocklists it for the job.
  EXPECT_TRUE(sched->has_worker(wa));
  const Lease l3 = lease(wa);
  EXPECT_EQ(l3.tile, 2);
  EXPECT_EQ(l3.window, (PixelWindow{128, 0, 192, 64}));
  EXPECT_EQ(l3.spp, 7u);
  EXPECT_TRUE(sched->fail(l3.id, "boom again").blocklisted);
  EXPECT_EQ(sched->acquire(wa).status, AcquireResult::no_work);

  // The stored pixels are exactly the uploaded ones.
  const auto px = store->tile_pixels(j);
  ASSERT_EQ(px.size(), 1u);
  EXPECT_EQ(px[0].first, 0);
  const Image img = tile_from_bytes(px[0].second, 64, 64);
  EXPECT_EQ(img.rgb, pixels_for(l0.window, 1.0f).rgb);
}

TEST_F(DatabaseTest, APausedJobStaysPausedAcrossARestart) {
  const std::string j = job();
  const std::string w = sched->register_worker("w").id;
  lease(w);
  ASSERT_EQ(sched->pause(j).status, PauseResult::changed);
  reopen();
  EXPECT_EQ(sched->job(j)->state, JobState::paused);
  EXPECT_EQ(sched->acquire(w).status, AcquireResult::no_work);
  ASSERT_EQ(sched->resume(j).status, PauseResult::changed);
  EXPECT_EQ(sched->job(j)->state, JobState::running);
  EXPECT_EQ(lease(w).tile, 1);
}

TEST_F(DatabaseTest, OwnersRequirementsCapsTagsAndLiveLeasesPerOwnerSurviveARestart) {
  JobParams p;
  p.width = 256;
  p.height = 64;
  p.tile_size = 64;
  p.spp = 1;
  p.scene_hash = "h";
  p.owner = "ana";
  p.require = {"bigmem", "site-a"};
  p.max_workers = 1;
  const std::string j = sched->add_job(p);
  const std::string big = sched->register_worker("big", 4, {"bigmem", "gpu", "site-a"}).id;
  const std::string other = sched->register_worker("other", 4, {"bigmem", "site-a"}).id;
  lease(big);
  reopen();
  const JobStatus s = *sched->job(j);
  EXPECT_EQ(s.params.owner, "ana");
  EXPECT_EQ(s.params.require, (std::vector<std::string>{"bigmem", "site-a"}));
  EXPECT_EQ(s.params.max_workers, 1);
  EXPECT_EQ(sched->worker(big)->tags, (std::vector<std::string>{"bigmem", "gpu", "site-a"}));
  // The lease held across the restart still counts against the job's cap of 1.
  EXPECT_EQ(sched->acquire(other).status, AcquireResult::no_work);
  EXPECT_EQ(*sched->job_owner(j), "ana");
}

TEST_F(DatabaseTest, TheAuditTrailSurvivesARestartPagesNewestFirstAndForgetsOldEntries) {
  for (int i = 0; i < 5; ++i)
    store->append_audit({0, 1000 + i, i % 2 ? "ben" : "ana", "user", "POST /v1/jobs/{id}/pause", "j-" + std::to_string(i),
                         "127.0.0.1", 200});
  reopen();
  protocol::AuditQuery q;
  q.limit = 2;
  const protocol::AuditList first = store->audit(q);
  ASSERT_EQ(first.entries.size(), 2u);
  EXPECT_EQ(first.entries[0].target, "j-4");
  EXPECT_EQ(first.entries[1].target, "j-3");
  ASSERT_TRUE(first.next);
  q.before = *first.next;
  q.user = "ana";
  q.limit = 10;
  const protocol::AuditList rest = store->audit(q);
  ASSERT_EQ(rest.entries.size(), 2u);  // j-2 and j-0
  EXPECT_EQ(rest.entries[0].target, "j-2");
  EXPECT_FALSE(rest.next);
  EXPECT_EQ(store->forget_audit(1003), 3);
  EXPECT_EQ(store->audit(protocol::AuditQuery{}).entries.size(), 2u);
}

TEST_F(DatabaseTest, ADrainedWorkerStaysDrainedAcrossARestart) {
  job();
  const std::string w = sched->register_worker("w").id, v = sched->register_worker("v").id;
  ASSERT_TRUE(sched->set_drained(w, true));
  reopen();
  EXPECT_EQ(sched->acquire(w).status, AcquireResult::no_work);
  EXPECT_EQ(sched->acquire(v).status, AcquireResult::granted);  // only the drained one
  ASSERT_TRUE(sched->set_drained(w, false));
  reopen();
  EXPECT_EQ(sched->acquire(w).status, AcquireResult::granted);
}

TEST_F(DatabaseTest, AWorkersSecretSurvivesARestartAsItsHashAndAForgottenWorkerStaysForgotten) {
  job();
  const RegisterResult w = sched->register_worker("w"), v = sched->register_worker("v");
  const Lease l = lease(w.id);
  reopen();
  EXPECT_EQ(sched->check_worker(w.id, w.secret), WorkerCheck::ok) << "the worker goes on after a restart";
  EXPECT_EQ(sched->check_worker(w.id, v.secret), WorkerCheck::wrong_secret);
  std::string holder;
  EXPECT_EQ(sched->check_lease_holder(l.id, w.secret, &holder), WorkerCheck::ok);
  EXPECT_EQ(sched->check_lease_holder(l.id, v.secret, &holder), WorkerCheck::wrong_secret);
  {
    Database db(dir / "tessera.db");
    Statement& st = db.statement("SELECT secret_sha256 FROM workers WHERE id = ?");
    st.bind_text(1, w.id);
    ASSERT_TRUE(st.step());
    EXPECT_EQ(st.text(0), worker_secret_hash(w.secret)) << "only the secret's hash is stored";
  }
  std::string file = read_file_bytes(dir / "tessera.db");
  if (fs::exists(dir / "tessera.db-wal")) file += read_file_bytes(dir / "tessera.db-wal");
  EXPECT_EQ(file.find(w.secret), std::string::npos) << "the secret itself is nowhere in the database";

  // v goes on being seen; w, its lease expired, is forgotten after its retention, and stays so across a restart.
  now += SchedulerConfig{}.worker_retention_ms / 2;
  EXPECT_EQ(sched->acquire(v.id).status, AcquireResult::granted);
  now += SchedulerConfig{}.worker_retention_ms / 2 + 1;
  EXPECT_EQ(sched->workers().size(), 1u);
  reopen();
  EXPECT_FALSE(sched->has_worker(w.id));
  EXPECT_EQ(sched->check_worker(w.id, w.secret), WorkerCheck::unknown_worker) << "it registers again";
  EXPECT_EQ(sched->check_worker(v.id, v.secret), WorkerCheck::ok);

  // A worker stored without a secret (by a build that had none) cannot prove who it is: it registers again.
  {
    Database db(dir / "tessera.db");
    db.exec("UPDATE workers SET secret_sha256 = ''");
  }
  reopen();
  EXPECT_EQ(sched->check_worker(v.id, v.secret), WorkerCheck::unknown_worker);
}

TEST_F(DatabaseTest, TileDetailsSurviveARestart) {
  const std::string j = job();  // 2 tiles
  const std::string w = sched->register_worker("w").id;
  const Lease l0 = lease(w);
  sched->fail(l0.id, "bad", {"a log line"});
  const Lease l1 = lease(w);  // tile 0 again
  now += 2'000;
  upload(l1, 1.0f);
  const Lease l2 = lease(w);  // tile 1, live across the restart
  now += 1'000;
  reopen();
  const auto tiles = sched->tiles(j);
  ASSERT_TRUE(tiles);
  const protocol::TileInfo& t0 = tiles->tiles[0];
  EXPECT_EQ(t0.attempts, 2);
  ASSERT_TRUE(t0.render_seconds);
  EXPECT_DOUBLE_EQ(*t0.render_seconds, 2.0);
  EXPECT_EQ(t0.rays, 100u);
  EXPECT_EQ(t0.rendered_by, w);
  ASSERT_EQ(t0.failures.size(), 1u);
  EXPECT_EQ(t0.failures[0].log, std::vector<std::string>{"a log line"});
  EXPECT_EQ(tiles->tiles[1].attempts, 1);
  EXPECT_EQ(tiles->tiles[1].worker, w);
  now += 500;  // the live lease's grant time was stored: its render time counts from the grant before the restart
  upload(l2, 2.0f);
  EXPECT_DOUBLE_EQ(*sched->tiles(j)->tiles[1].render_seconds, 1.5);
}

TEST_F(DatabaseTest, AChangedPriorityIsStored) {
  const std::string j = job();  // priority 3
  ASSERT_EQ(sched->set_priority(j, 11).status, PriorityResult::changed);
  reopen();
  EXPECT_EQ(sched->job(j)->params.priority, 11);
}

TEST_F(DatabaseTest, IdsNeverRepeatAfterARestart) {
  std::set<std::string> ids;
  const std::string j = job();
  ids.insert(j);
  const std::string w = sched->register_worker("w").id;
  ids.insert(w);
  ids.insert(lease(w).id);
  ids.insert(sched->new_job_id());
  reopen("a");  // the same tag on purpose: the stored sequence alone keeps ids apart
  EXPECT_TRUE(ids.insert(job()).second);
  const std::string w2 = sched->register_worker("w2").id;
  EXPECT_TRUE(ids.insert(w2).second);
  EXPECT_TRUE(ids.insert(lease(w2).id).second);
}

TEST_F(DatabaseTest, JobFinishedAcrossARestartKeepsItsImage) {
  const std::string j = job(128, 64, 64);
  const std::string w = sched->register_worker("w").id;
  const Lease a = lease(w), b = lease(w);
  upload(a, 2.0f);
  reopen();
  upload(b, 3.0f);
  EXPECT_EQ(sched->unfinalized_jobs(), std::vector<std::string>{j});  // what Api::recover would finalize
  reopen();
  EXPECT_EQ(sched->unfinalized_jobs(), std::vector<std::string>{j});
  const auto px = store->tile_pixels(j);
  ASSERT_EQ(px.size(), 2u);
  EXPECT_EQ(tile_from_bytes(px[1].second, 64, 64).rgb, pixels_for(b.window, 3.0f).rgb);
  sched->complete_job(j);
  reopen();
  EXPECT_EQ(sched->job(j)->state, JobState::done);
  EXPECT_TRUE(sched->unfinalized_jobs().empty());
}

// The machine stopped after done tiles' rows reached the disk but before their bytes did (the flush that would have
// acknowledged them never came): at the restart those tiles are pending again, and their job, done by then, running,
// instead of the coordinator failing; the repair is stored, and the tiles rendered again complete the job.
TEST_F(DatabaseTest, TilesWhoseBytesAreMissingOrDamagedArePendingAgainAfterARestart) {
  const std::string j = job(192, 64, 64);
  const std::string w = sched->register_worker("w").id;
  const Lease a = lease(w), b = lease(w), c = lease(w);
  upload(a, 1.0f);
  upload(b, 2.0f);
  upload(c, 3.0f);
  sched->complete_job(j);
  ASSERT_EQ(sched->job(j)->state, JobState::done);
  sched.reset();
  store.reset();
  const fs::path file = dir / DurableStore::kPixelsDir / (j + ".pixels");
  const uintmax_t tile = fs::file_size(file) / 3;  // the tiles in upload order, one after another
  {
    // b's bytes damaged in the middle, c's cut short by a byte.
    std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(std::streamoff(tile + tile / 2));
    const char byte = char(f.get());
    f.seekp(std::streamoff(tile + tile / 2));
    f.put(char(~byte));
  }
  fs::resize_file(file, 3 * tile - 1);
  for (int restart = 0; restart < 2; ++restart) {  // the second finds the repair stored
    open();
    EXPECT_EQ(sched->job(j)->state, JobState::running);
    EXPECT_EQ(sched->job(j)->tiles.done, 1);
    EXPECT_EQ(sched->job(j)->tiles.pending, 2);
    const auto px = store->tile_pixels(j);
    ASSERT_EQ(px.size(), 1u);
    EXPECT_EQ(px[0].first, a.tile);
    EXPECT_EQ(tile_from_bytes(px[0].second, 64, 64).rgb, pixels_for(a.window, 1.0f).rgb);
    sched.reset();
    store.reset();
  }
  open();
  const Lease b2 = lease(w), c2 = lease(w);
  EXPECT_EQ((std::set<int64_t>{b2.tile, c2.tile}), (std::set<int64_t>{b.tile, c.tile}));
  upload(b2, 2.0f);
  EXPECT_TRUE(sched->claim_result(c2.id).status == ResultClaim::proceed);
  EXPECT_TRUE(sched->finish_result(c2.id, 100, tile_bytes(pixels_for(c2.window, 3.0f))).last);
  sched->complete_job(j);
  reopen();
  EXPECT_EQ(sched->job(j)->state, JobState::done);
  EXPECT_EQ(store->tile_pixels(j).size(), 3u);
}

// A done job whose result file is in place is not read back at a start (its result holds its pixels; a long history
// would cost its whole size at every start): a damaged tile of it stays done until something reads it, which then
// gets an error naming the tile and the file.
TEST_F(DatabaseTest, ADoneJobWithItsResultIsNotReadBackAtAStart) {
  const std::string j = job(128, 64, 64);
  const std::string w = sched->register_worker("w").id;
  upload(lease(w), 1.0f);
  upload(lease(w), 2.0f);
  sched->complete_job(j);
  store->write_result(j, [](const fs::path& f) { std::ofstream(f) << "merged"; });
  sched.reset();
  store.reset();
  const fs::path file = dir / DurableStore::kPixelsDir / (j + ".pixels");
  fs::resize_file(file, fs::file_size(file) - 1);
  open();
  EXPECT_EQ(sched->job(j)->state, JobState::done);
  EXPECT_EQ(sched->job(j)->tiles.done, 2);
  try {
    store->tile_pixels(j);
    ADD_FAILURE() << "a cut tile read back";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
}

// A database of schema version 1 keeps done tiles' bytes in their rows: it opens (upgraded to version 2), those tiles
// read as they were, and a tile rendered again has its new bytes in the job's pixel file.
TEST_F(DatabaseTest, ADatabaseOfVersion1WithPixelsInItsRowsKeepsLoading) {
  const std::string j = job(128, 64, 64);
  const std::string w = sched->register_worker("w").id;
  const Lease a = lease(w), b = lease(w);
  upload(a, 1.0f);
  upload(b, 2.0f);
  const auto before = store->tile_pixels(j);
  ASSERT_EQ(before.size(), 2u);
  sched.reset();
  store.reset();
  const fs::path file = dir / DurableStore::kPixelsDir / (j + ".pixels");
  const auto version = [&] {
    Database db(dir / DurableStore::kFileName);
    Statement& st = db.statement("SELECT value FROM meta WHERE key = 'schema_version'");
    return st.step() ? st.integer(0) : -1;
  };
  {
    // As version 1 made it: its CHECK, the bytes in the rows, no pixel file.
    Database db(dir / DurableStore::kFileName);
    for (const auto& [index, bytes] : before)
      db.statement("UPDATE tiles SET pixels = ?, pixel_offset = NULL, pixel_length = NULL, pixel_checksum = NULL"
                   " WHERE job = ? AND idx = ?")
          .bind_blob(1, bytes)
          .bind_text(2, j)
          .bind(3, index)
          .run();
    Statement& get = db.statement("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'tiles'");
    ASSERT_TRUE(get.step());
    std::string sql = get.text(0);
    get.reset();
    const std::string v2 = " OR pixel_length IS NOT NULL";
    ASSERT_NE(sql.find(v2), std::string::npos) << sql;
    sql.erase(sql.find(v2), v2.size());
    sql.replace(0, sql.find('('), "CREATE TABLE tiles_v1");
    db.exec(sql);
    db.exec("INSERT INTO tiles_v1 SELECT * FROM tiles; DROP TABLE tiles; ALTER TABLE tiles_v1 RENAME TO tiles");
    db.exec("UPDATE meta SET value = 1 WHERE key = 'schema_version'");
  }
  fs::remove(file);
  ASSERT_EQ(version(), 1);
  open();
  EXPECT_EQ(version(), 2);
  EXPECT_EQ(store->tile_pixels(j), before);
  EXPECT_EQ(sched->job(j)->tiles.done, 2);
  // Rendered again: the new bytes in the pixel file, the other tile's still in its row.
  ASSERT_EQ(sched->requeue(j, a.tile).status, RequeueResult::requeued);
  const Lease again = lease(w);
  ASSERT_EQ(again.tile, a.tile);
  upload(again, 5.0f);
  EXPECT_TRUE(fs::exists(file));
  reopen();
  const auto after = store->tile_pixels(j);
  ASSERT_EQ(after.size(), 2u);
  for (const auto& [index, bytes] : after)
    EXPECT_EQ(tile_from_bytes(bytes, 64, 64).rgb,
              pixels_for(index == a.tile ? a.window : b.window, index == a.tile ? 5.0f : 2.0f).rgb);
  // The version-2 CHECK still refuses a done tile without either.
  Database db(dir / DurableStore::kFileName);
  EXPECT_THROW(db.exec("UPDATE tiles SET pixels = NULL, pixel_length = NULL WHERE idx = " + std::to_string(b.tile)),
               StorageError);
}

// The coordinator died between storing a job's last tile and writing its result: starting it again writes the result
// from the stored tiles and marks the job done.
TEST_F(DatabaseTest, CoordinatorStartFinishesAJobWhoseTilesWereAllStored) {
  const std::string j = job(128, 64, 64);
  const std::string w = sched->register_worker("w").id;
  const Lease a = lease(w), b = lease(w);
  upload(a, 2.0f);
  upload(b, 3.0f);
  sched.reset();
  store.reset();
  CoordinatorOptions o;
  o.port = 0;
  o.data_dir = dir;
  Coordinator c(o);  // recovers in its constructor, before serving
  const fs::path result = dir / "jobs" / j / "result.exr";
  ASSERT_TRUE(fs::exists(result));
  const ExrImage exr = read_exr(result);
  ASSERT_EQ(exr.pixels.width, 128);
  for (const auto& [l, base] : {std::pair{a, 2.0f}, std::pair{b, 3.0f}}) {
    const Image want = pixels_for(l.window, base);
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) ASSERT_EQ(exr.pixels.at(l.window.x0 + x, y), want.at(x, y)) << x << "," << y;
  }
  DurableStore reread(dir);
  Scheduler after(SchedulerConfig{10'000, 3, 2, "b"}, [this] { return now; }, reread);
  EXPECT_EQ(after.job(j)->state, JobState::done);
}

// What a SIGKILL can leave in the data folder (found by the chaos soak, tests/soak/): an upload's scratch file in
// DIR/tmp/ (written before validation, removed after), the temp file of a result or blob write (write, fsync, rename).
// A coordinator started on the folder removes them and keeps everything else.
TEST_F(DatabaseTest, CoordinatorStartRemovesTheTempFilesOfAKilledRun) {
  const std::string j = job(64, 64, 64);
  sched.reset();
  store.reset();
  const auto write = [](const fs::path& p, const std::string& text) {
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
  };
  const std::string sha(64, 'a');
  write(dir / "tmp" / "result-L-1-0a1b2c.exr", "half an upload");
  write(dir / "tmp" / "nested" / "x", "?");
  write(dir / "jobs" / j / "result.exr.tmp", "half a result");
  write(dir / "blobs" / "aa" / (sha + ".0a1b2c3d4e5f.tmp"), "half a blob");
  write(dir / "blobs" / "aa" / sha, "a blob");
  CoordinatorOptions o;
  o.port = 0;
  o.data_dir = dir;
  {
    Coordinator c(o);
  }
  EXPECT_TRUE(fs::is_directory(dir / "tmp"));
  EXPECT_TRUE(fs::is_empty(dir / "tmp"));
  EXPECT_FALSE(fs::exists(dir / "jobs" / j / "result.exr.tmp"));
  EXPECT_FALSE(fs::exists(dir / "blobs" / "aa" / (sha + ".0a1b2c3d4e5f.tmp")));
  EXPECT_TRUE(fs::exists(dir / "blobs" / "aa" / sha));
  EXPECT_TRUE(fs::exists(dir / "tessera.db"));
  DurableStore reopened(dir);  // nothing left to remove the second time
  EXPECT_EQ(reopened.leftovers_removed(), 0u);
  DiskBlobStore blobs(dir / "blobs");
  EXPECT_EQ(blobs.leftovers_removed(), 0u);
  EXPECT_TRUE(blobs.has(sha));
}

// A commit that fails takes back what the accepted tile would have added to its worker and its job: the worker's
// tiles, rays and render time, and the job's rays, stay those of the tiles really stored.
TEST_F(DatabaseTest, AFailedCommitLeavesTheWorkersTilesRaysAndRenderTimeAsTheyWere) {
  const std::string j = job(128, 64, 64);  // two tiles
  const std::string w = sched->register_worker("w").id;
  const Lease first = lease(w);
  now += 2'000;
  upload(first, 1.0f);
  const auto worker_row = [&] {
    for (const protocol::WorkerInfo& info : sched->workers())
      if (info.id == w) return info;
    ADD_FAILURE() << "worker " << w << " not listed";
    return protocol::WorkerInfo{};
  };
  const protocol::WorkerInfo before = worker_row();
  ASSERT_EQ(before.tiles_done, 1);
  ASSERT_EQ(before.rays, 100u);
  ASSERT_GT(before.render_seconds, 0.0);
  const uint64_t job_rays = sched->job(j)->rays;
  const Lease second = lease(w);
  now += 3'000;
  ASSERT_EQ(sched->claim_result(second.id).status, ResultClaim::proceed);
  EXPECT_THROW(sched->finish_result(second.id, 5'000), StorageError);  // no pixels: the database refuses the commit
  const protocol::WorkerInfo after = worker_row();
  EXPECT_EQ(after.tiles_done, before.tiles_done);
  EXPECT_EQ(after.rays, before.rays);
  EXPECT_EQ(after.render_seconds, before.render_seconds);
  EXPECT_EQ(sched->job(j)->rays, job_rays);
  // The upload is given back, as the coordinator does after a failed commit, and the same lease delivers it after
  // all: counted once.
  sched->abandon_result(second.id);
  ASSERT_EQ(sched->claim_result(second.id).status, ResultClaim::proceed);
  EXPECT_TRUE(sched->finish_result(second.id, 5'000, tile_bytes(pixels_for(second.window, 2.0f))).last);
  EXPECT_EQ(worker_row().tiles_done, 2);
  EXPECT_EQ(worker_row().rays, 5'100u);
  EXPECT_EQ(sched->job(j)->rays, job_rays + 5'000);
  reopen();  // the job's rays are stored (a worker's figures count from the coordinator's start)
  EXPECT_EQ(sched->job(j)->rays, job_rays + 5'000);
}

TEST_F(DatabaseTest, ATileIsNeverDoneWithoutItsPixels) {
  const std::string j = job(64, 64, 64);
  const std::string w = sched->register_worker("w").id;
  const Lease l = lease(w);
  ASSERT_EQ(sched->claim_result(l.id).status, ResultClaim::proceed);
  // No pixels: the database refuses, and the scheduler does not pretend the tile is done.
  EXPECT_THROW(sched->finish_result(l.id, 5), StorageError);
  EXPECT_EQ(sched->job(j)->tiles.done, 0);
  EXPECT_EQ(sched->counters().tiles_rendered, 0u);
  reopen();
  // The unacknowledged upload's tile is pending again, and the same lease can still deliver it.
  EXPECT_EQ(sched->job(j)->tiles.pending, 1);
  EXPECT_TRUE(store->tile_pixels(j).empty());
  ASSERT_EQ(sched->claim_result(l.id).status, ResultClaim::proceed);
  EXPECT_TRUE(sched->finish_result(l.id, 5, tile_bytes(pixels_for(l.window, 1.0f))).last);
  reopen();
  EXPECT_EQ(sched->job(j)->tiles.done, 1);
}

TEST_F(DatabaseTest, ABatchIsStoredWhollyOrNotAtAll) {
  const std::string j = job(64, 64, 64);
  JobRow row{*sched->job(j), 99, {}, {}};
  row.status.state = JobState::failed;
  SchedulerChanges c;
  c.jobs.push_back(row);
  c.tiles.push_back(TileRow{j, 0, TileState::done, "", {}, std::nullopt, {}, 0, -1, 0, ""});  // done without pixels
  EXPECT_THROW(store->apply(c), StorageError);
  reopen();
  EXPECT_EQ(sched->job(j)->state, JobState::queued);
  EXPECT_EQ(sched->job(j)->tiles.pending, 1);
}

TEST_F(DatabaseTest, AMergeInterruptedByACrashIsRetriedOrPendingAgain) {
  const std::string j = job(128, 64, 64);
  const std::string w = sched->register_worker("w").id;
  const Lease l0 = lease(w), l1 = lease(w);
  // Killed right after the claim: the claim was not stored on its own, so the lease is still live and the worker's
  // retried upload goes through.
  ASSERT_EQ(sched->claim_result(l0.id).status, ResultClaim::proceed);
  reopen();
  EXPECT_EQ(sched->job(j)->tiles.leased, 2);
  ASSERT_EQ(sched->claim_result(l0.id).status, ResultClaim::proceed);
  sched->finish_result(l0.id, 1, tile_bytes(pixels_for(l0.window, 1.0f)));
  // Killed while the merging state was stored by another operation: the tile is pending again.
  ASSERT_EQ(sched->claim_result(l1.id).status, ResultClaim::proceed);
  sched->register_worker("other");
  reopen();
  EXPECT_EQ(sched->job(j)->tiles.pending, 1);
  EXPECT_EQ(sched->job(j)->tiles.done, 1);
  EXPECT_EQ(sched->counters().active_leases, 0);
  const Lease again = lease(w);
  EXPECT_EQ(again.tile, 1);
  EXPECT_NE(again.id, l1.id);
}

TEST_F(DatabaseTest, RefusesANewerSchema) {
  sched.reset();
  store.reset();
  {
    Database db(dir / "tessera.db");
    db.exec("UPDATE meta SET value = 99 WHERE key = 'schema_version'");
  }
  try {
    DurableStore s(dir);
    FAIL() << "opened a database of schema version 99";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 99"), std::string::npos) << e.what();
  }
}

TEST_F(DatabaseTest, JobRecordsRoundTrip) {
  EXPECT_FALSE(store->load_record("j-x"));
  const nlohmann::json rec = {{"scene", {{"a", 1}}}, {"spp", 4}};
  store->save_record("j-x", rec);
  reopen();
  EXPECT_EQ(store->load_record("j-x"), rec);
  EXPECT_EQ(store->result_path("j-x"), dir / "jobs" / "j-x" / "result.exr");
}

TEST_F(DatabaseTest, ARaisedSppAndTileStatesSurviveARestart) {
  const std::string j = job();  // 2 tiles at 7 spp
  const std::string w = sched->register_worker("w").id;
  const Lease l = lease(w);
  upload(l, 1.f);
  EXPECT_FALSE(store->tile_state_spp(j, 0));
  store->save_tile_state(j, 0, 7, std::string("exr \0 bytes", 11));
  store->save_tile_state(j, 0, 7, "replaced");
  ASSERT_EQ(sched->raise_spp(j, 28).status, RaiseResult::raised);
  reopen();
  EXPECT_EQ(sched->job(j)->params.spp, 28u);
  EXPECT_EQ(sched->job(j)->tiles.pending, 2);
  EXPECT_EQ(store->tile_state_spp(j, 0), 7u);
  EXPECT_EQ(store->tile_state(j, 0), (std::pair<uint32_t, std::string>{7, "replaced"}));
  EXPECT_FALSE(store->tile_state(j, 1));
  const Lease again = lease(w);
  EXPECT_EQ(again.tile, 0);
  EXPECT_EQ(again.spp, 28u);
}

TEST_F(DatabaseTest, DatabaseErrorsNameTheStatement) {
  Database db(dir / "other.db");
  try {
    db.exec("SELECT * FROM no_such_table");
    FAIL() << "no error";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_table"), std::string::npos) << e.what();
  }
  Statement& st = db.statement("PRAGMA journal_mode");
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.text(0), "wal");
}

// A database opens in WAL mode with the synchronous mode it is asked for, FULL unless told otherwise (strace of
// `serve --durability process` on a new folder shows no fsync or fdatasync: the mode is set before the WAL switch).
TEST_F(DatabaseTest, OpensInWalModeWithTheSynchronousModeAskedFor) {
  for (const auto& [mode, value] : {std::pair{"OFF", 0}, std::pair{"NORMAL", 1}, std::pair{"FULL", 2}}) {
    Database db(dir / (std::string("sync-") + mode + ".db"), mode);
    Statement& st = db.statement("PRAGMA synchronous");
    ASSERT_TRUE(st.step());
    EXPECT_EQ(st.integer(0), value) << mode;
    Statement& journal = db.statement("PRAGMA journal_mode");
    ASSERT_TRUE(journal.step());
    EXPECT_EQ(journal.text(0), "wal") << mode;
  }
  Database plain(dir / "default.db");
  Statement& st = plain.statement("PRAGMA synchronous");
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.integer(0), 2) << "FULL unless asked otherwise";
}

TEST(TileBytes, RoundTripAndSizeCheck) {
  Image img = Image::make(3, 2);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) - 2.5f;
  EXPECT_EQ(tile_from_bytes(tile_bytes(img), 3, 2).rgb, img.rgb);
  EXPECT_THROW(tile_from_bytes(tile_bytes(img), 2, 2), std::invalid_argument);
}

}  // namespace
}  // namespace tessera::server

namespace tessera::server {
namespace {

// Records, per scheduler operation, whether it asked the store to flush to disk.
struct RecordingStore final : SchedulerStore {
  int applies = 0, syncs = 0;
  void apply(const SchedulerChanges&) override { ++applies; }
  SchedulerSnapshot load() override { return {}; }
  void sync() override { ++syncs; }
  // True when the last operation stored changes and flushed them; resets the counts.
  bool flushed() {
    const bool r = syncs > 0;
    EXPECT_LE(syncs, applies) << "a flush without stored changes";
    applies = syncs = 0;
    return r;
  }
};

TEST(SchedulerSync, OnlyAcknowledgementsWaitForTheDisk) {
  RecordingStore store;
  int64_t now = 1'000;
  Scheduler s(SchedulerConfig{10'000, 3, 2, "s"}, [&] { return now; }, store);
  const std::string w = s.register_worker("w").id;
  EXPECT_FALSE(store.flushed()) << "a registration is not an acknowledgement that must survive a power cut";
  JobParams p;
  p.width = 8;
  p.height = 4;
  p.tile_size = 4;
  p.spp = 1;
  const std::string j = s.add_job(p);
  EXPECT_TRUE(store.flushed()) << "a submission must be on disk before the client hears of it";
  const Lease l = s.acquire(w).lease;
  EXPECT_FALSE(store.flushed()) << "a lease grant";
  s.heartbeat(l.id, 10);
  EXPECT_FALSE(store.flushed()) << "a heartbeat";
  ASSERT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  s.finish_result(l.id, 0, std::string(4 * 4 * 3 * sizeof(float), '\0'));
  EXPECT_TRUE(store.flushed()) << "a done tile must be on disk before the worker hears 200";
  s.acquire(w);
  EXPECT_FALSE(store.flushed());
  s.cancel(j);
  EXPECT_TRUE(store.flushed()) << "a job's end";
}


// A scheduler over a MemoryStore: done tiles' pixels, records and tile states are there until the job is purged;
// nothing comes back after a restart, and opening it empties the jobs and scratch folders.
// A fresh folder per test, removed afterwards even when an assertion ends the test early.
class MemoryStoreTest : public testing::TempDirTest {};

TEST_F(MemoryStoreTest, KeepsPixelsRecordsAndTileStatesUntilPurgedAndNothingAcrossARestart) {
  const fs::path dir = file("data");
  fs::create_directories(dir / "jobs" / "j-old");
  fs::create_directories(dir / "tmp");
  std::ofstream(dir / "jobs" / "j-old" / "result.exr") << "old";
  std::ofstream(dir / "tmp" / "upload") << "half";
  int64_t now = 1'000'000;
  {
    MemoryStore store(dir);
    EXPECT_GE(store.leftovers_removed(), 2u);
    EXPECT_FALSE(fs::exists(dir / "jobs" / "j-old"));
    EXPECT_FALSE(fs::exists(dir / "tmp" / "upload"));
    EXPECT_EQ(store.where(), "memory");
    Scheduler sched(SchedulerConfig{10'000, 3, 2, "m"}, [&] { return now; }, store);
    JobParams p;
    p.name = "n";
    p.width = 128;
    p.height = 64;
    p.tile_size = 64;
    p.spp = 1;
    p.scene_hash = "hash";
    const std::string j = sched.add_job(p);
    const std::string w = sched.register_worker("w").id;
    std::vector<std::string> sent;
    for (int t = 0; t < 2; ++t) {
      const AcquireResult r = sched.acquire(w);
      ASSERT_EQ(r.status, AcquireResult::granted);
      ASSERT_EQ(sched.claim_result(r.lease.id).status, ResultClaim::proceed);
      Image img = Image::make(r.lease.window.width(), r.lease.window.height());
      for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(t) + float(i);
      sent.emplace_back(tile_bytes(img));
      sched.finish_result(r.lease.id, 1, sent.back());
    }
    const auto pixels = store.tile_pixels(j);
    ASSERT_EQ(pixels.size(), 2u);
    EXPECT_EQ(pixels[0], std::make_pair(int64_t(0), sent[0]));
    EXPECT_EQ(pixels[1], std::make_pair(int64_t(1), sent[1]));
    store.save_record(j, nlohmann::json{{"k", 1}});
    EXPECT_EQ(store.load_record(j), nlohmann::json({{"k", 1}}));
    store.save_tile_state(j, 1, 8, "exr-bytes");
    EXPECT_EQ(store.tile_state_spp(j, 1), 8u);
    EXPECT_EQ(store.tile_state(j, 1), std::make_pair(uint32_t(8), std::string("exr-bytes")));
    EXPECT_FALSE(store.tile_state(j, 0));
    store.write_result(j, [](const fs::path& f) { std::ofstream(f) << "merged"; });
    EXPECT_EQ(store.jobs_with_outputs(), std::vector<std::string>{j});
    sched.complete_job(j);  // after the merged result was written
    ASSERT_EQ(sched.purge(j).status, PurgeResult::purged);
    EXPECT_TRUE(store.tile_pixels(j).empty());
    EXPECT_FALSE(store.load_record(j));
    EXPECT_FALSE(store.tile_state(j, 1));
    store.remove_outputs(j);
    EXPECT_TRUE(store.jobs_with_outputs().empty());
    sched.add_job(p);
  }
  MemoryStore again(dir);
  Scheduler restarted(SchedulerConfig{10'000, 3, 2, "m"}, [&] { return now; }, again);
  EXPECT_TRUE(restarted.jobs().empty());
}

// A folder a durable coordinator used is refused, and its results stay.
TEST_F(MemoryStoreTest, RefusesAFolderHoldingADurableDatabase) {
  const fs::path dir = file("data");
  { DurableStore durable(dir); }
  fs::create_directories(dir / "jobs" / "j-1");
  std::ofstream(dir / "jobs" / "j-1" / "result.exr") << "kept";
  try {
    MemoryStore store(dir);
    ADD_FAILURE() << "opened";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("durable coordinator's database"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(dir / "jobs" / "j-1" / "result.exr"));
  EXPECT_THROW(open_coordinator_store(dir, Durability::none), StorageError);
  EXPECT_NO_THROW(open_coordinator_store(dir, Durability::process));
}

}  // namespace
}  // namespace tessera::server
