#include "server/scheduler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

namespace tessera::server {
namespace {

// A scheduler on a manual clock with 10 s leases; a 2x2-tile job is 128x128 at tile size 64.
struct SchedulerTest : ::testing::Test {
  int64_t now = 1'000'000;
  Scheduler s{SchedulerConfig{10'000, 3, 2, ""}, [this] { return now; }};

  std::string job(int priority = 0, int w = 128, int h = 128, int ts = 64) {
    JobParams p;
    p.priority = priority;
    p.width = w;
    p.height = h;
    p.tile_size = ts;
    p.spp = 4;
    p.scene_hash = "abc";
    return s.add_job(p);
  }
  Lease lease(const std::string& worker) {
    const AcquireResult r = s.acquire(worker);
    EXPECT_EQ(r.status, AcquireResult::granted);
    return r.lease;
  }
  // Uploads a result the way the HTTP layer does: claim, copy (nothing here), finish.
  ResultClaim::Status upload(const std::string& lease_id, bool* last = nullptr) {
    const ResultClaim c = s.claim_result(lease_id);
    if (c.status == ResultClaim::proceed) {
      const FinishResult f = s.finish_result(lease_id, 10);
      if (last) *last = f.last;
    }
    return c.status;
  }
};

TEST_F(SchedulerTest, EmptyQueueIsNoWorkNotAnError) {
  const std::string w = s.register_worker("a").id;
  EXPECT_EQ(s.acquire(w).status, AcquireResult::no_work);
  EXPECT_EQ(s.acquire("w-nobody").status, AcquireResult::unknown_worker);
  EXPECT_FALSE(s.has_worker("w-nobody"));
  EXPECT_TRUE(s.has_worker(w));
}

TEST_F(SchedulerTest, LeasableTilesCountWhatAcquireCouldGrantAndNoteNewWork) {
  int noted = 0;
  s.on_work([&] { ++noted; });
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  EXPECT_EQ(s.leasable_tiles(a), 0);
  EXPECT_EQ(s.leasable_tiles("w-nobody"), 0);
  const std::string j1 = job(5), j2 = job(0);  // 4 tiles each
  EXPECT_EQ(noted, 2);
  EXPECT_EQ(s.leasable_tiles(a), 8);
  // Counting takes nothing; a lease does.
  EXPECT_EQ(s.leasable_tiles(a), 8);
  Lease l = lease(a);
  EXPECT_EQ(l.job, j1);
  EXPECT_EQ(s.leasable_tiles(b), 7);
  // A worker blocklisted for j1 (two failures) counts only j2's tiles; the failed tiles went back: new work.
  const int before = noted;
  s.fail(l.id, "x");
  l = lease(a);
  s.fail(l.id, "x");
  EXPECT_EQ(noted, before + 2);
  EXPECT_EQ(s.leasable_tiles(a), 4);
  EXPECT_EQ(s.leasable_tiles(b), 8);
  // Paused jobs and drained workers have none; resuming and undraining are new work.
  ASSERT_EQ(s.pause(j2).status, PauseResult::changed);
  EXPECT_EQ(s.leasable_tiles(a), 0);
  EXPECT_EQ(s.leasable_tiles(b), 4);
  ASSERT_EQ(s.resume(j2).status, PauseResult::changed);
  EXPECT_EQ(noted, before + 3);
  s.set_drained(b, true);
  EXPECT_EQ(s.leasable_tiles(b), 0);
  s.set_drained(b, false);
  EXPECT_EQ(noted, before + 4);
  EXPECT_EQ(s.leasable_tiles(b), 8);
}

TEST_F(SchedulerTest, TilesLeasedInRowMajorOrderWithWindows) {
  const std::string j = job(0, 100, 70, 64);  // 2 columns x 2 rows; last column 36 wide, last row 6 high
  const std::string w = s.register_worker("a").id;
  const Lease l0 = lease(w), l1 = lease(w), l2 = lease(w), l3 = lease(w);
  EXPECT_EQ(l0.tile, 0);
  EXPECT_EQ(l1.tile, 1);
  EXPECT_EQ(l2.tile, 2);
  EXPECT_EQ(l3.tile, 3);
  EXPECT_EQ(l1.window, (PixelWindow{64, 0, 100, 64}));
  EXPECT_EQ(l3.window, (PixelWindow{64, 64, 100, 70}));
  EXPECT_EQ(l0.job, j);
  EXPECT_EQ(l0.spp, 4u);
  EXPECT_EQ(l0.scene_hash, "abc");
  EXPECT_EQ(l0.deadline_ms, now + 10'000);
  EXPECT_EQ(s.acquire(w).status, AcquireResult::no_work);
  const JobStatus st = *s.job(j);
  EXPECT_EQ(st.state, JobState::running);
  EXPECT_EQ(st.started_ms, now);
  EXPECT_EQ(st.tiles.total, 4);
  EXPECT_EQ(st.tiles.leased, 4);
  EXPECT_EQ(st.tiles.pending, 0);
}

TEST_F(SchedulerTest, PriorityThenAgeOrder) {
  const std::string low = job(0);
  now += 1;
  const std::string high_old = job(5);
  now += 1;
  const std::string high_new = job(5);
  const std::string w = s.register_worker("a").id;
  for (int i = 0; i < 4; ++i) EXPECT_EQ(lease(w).job, high_old);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(lease(w).job, high_new);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(lease(w).job, low);
  EXPECT_EQ(s.job(low)->state, JobState::running);
  // Same priority and same millisecond: submission order decides.
  const std::string a = job(9), b = job(9);
  EXPECT_EQ(lease(w).job, a);
  (void)b;
}

TEST_F(SchedulerTest, NewestFirstListing) {
  const std::string a = job(), b = job(7), c = job();
  const auto all = s.jobs();
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0].id, c);
  EXPECT_EQ(all[1].id, b);
  EXPECT_EQ(all[2].id, a);
  EXPECT_FALSE(s.job("j-none"));
}

TEST_F(SchedulerTest, LeaseExpiresAndTileIsReleasedToTheNextWorker) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  const Lease la = lease(a);
  now += 10'000;  // exactly at the deadline: still live
  EXPECT_EQ(s.heartbeat(la.id).status, HeartbeatResult::ok);
  now += 10'001;  // past the extended deadline
  EXPECT_EQ(s.heartbeat(la.id).status, HeartbeatResult::gone);
  EXPECT_EQ(s.counters().lease_expiries, 1u);
  const Lease lb = lease(b);
  EXPECT_EQ(lb.tile, la.tile);
  EXPECT_NE(lb.id, la.id);
  EXPECT_EQ(s.job(j)->tiles.leased, 1);
  EXPECT_EQ(s.heartbeat("l-none").status, HeartbeatResult::unknown);
}

TEST_F(SchedulerTest, HeartbeatExtendsTheDeadline) {
  job();
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  for (int i = 0; i < 5; ++i) {
    now += 6'000;  // longer than a lease in total, never longer than one between heartbeats
    const HeartbeatResult h = s.heartbeat(l.id, 100);
    ASSERT_EQ(h.status, HeartbeatResult::ok);
    EXPECT_EQ(h.deadline_ms, now + 10'000);
  }
  EXPECT_EQ(s.counters().lease_expiries, 0u);
  EXPECT_EQ(s.counters().rays, 500u);
}

TEST_F(SchedulerTest, CompletionMakesTheLastTileReportLast) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  std::vector<Lease> ls;
  for (int i = 0; i < 4; ++i) ls.push_back(lease(a));
  bool last = true;
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(upload(ls[size_t(i)].id, &last), ResultClaim::proceed);
    EXPECT_FALSE(last);
  }
  EXPECT_EQ(s.job(j)->tiles.done, 3);
  EXPECT_EQ(upload(ls[3].id, &last), ResultClaim::proceed);
  EXPECT_TRUE(last);
  EXPECT_EQ(s.job(j)->state, JobState::running);  // done only once the image is written
  s.complete_job(j);
  const JobStatus st = *s.job(j);
  EXPECT_EQ(st.state, JobState::done);
  EXPECT_EQ(st.finished_ms, now);
  EXPECT_EQ(st.rays, 40u);
  EXPECT_EQ(st.workers, std::vector<std::string>{a});
  EXPECT_EQ(s.counters().tiles_rendered, 4u);
  EXPECT_EQ(s.counters().jobs[JobState::done], 1);
  // Heartbeats on completed leases tell the worker to stop; a repeat upload is a duplicate.
  EXPECT_EQ(s.heartbeat(ls[0].id).status, HeartbeatResult::gone);
  EXPECT_EQ(upload(ls[0].id), ResultClaim::duplicate);
  EXPECT_EQ(s.cancel(j).status, CancelResult::already_ended);
}

TEST_F(SchedulerTest, DuplicateUploadIsAcknowledgedAndNotMergedTwice) {
  const std::string j = job(0, 64, 64, 64);  // one tile
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  EXPECT_EQ(s.check_result(l.id).status, ResultClaim::proceed);
  EXPECT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  // A retry arriving while the first upload is being merged is a duplicate.
  EXPECT_EQ(s.claim_result(l.id).status, ResultClaim::duplicate);
  EXPECT_TRUE(s.finish_result(l.id).last);
  EXPECT_EQ(upload(l.id), ResultClaim::duplicate);
  EXPECT_EQ(s.check_result(l.id).status, ResultClaim::duplicate);
  EXPECT_EQ(s.job(j)->tiles.done, 1);
  EXPECT_EQ(s.counters().tiles_rendered, 1u);
  EXPECT_EQ(s.check_result("l-none").status, ResultClaim::unknown);
}

TEST_F(SchedulerTest, LateUploadOfAnExpiredLeaseIsAcceptedAndRevokesTheNewLease) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  const Lease la = lease(a);
  now += 20'000;
  const Lease lb = lease(b);
  ASSERT_EQ(lb.tile, la.tile);
  bool last = false;
  EXPECT_EQ(upload(la.id, &last), ResultClaim::proceed);  // the pixels are the same whoever rendered them
  EXPECT_TRUE(last);
  EXPECT_EQ(s.heartbeat(lb.id).status, HeartbeatResult::gone);
  EXPECT_EQ(upload(lb.id), ResultClaim::duplicate);
  EXPECT_EQ(s.job(j)->tiles.done, 1);
  EXPECT_EQ(s.counters().tiles_rendered, 1u);
}

TEST_F(SchedulerTest, LateUploadWhileTileIsPendingIsAccepted) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id;
  const Lease la = lease(a);
  now += 20'000;
  s.expire();
  EXPECT_EQ(s.job(j)->tiles.pending, 1);
  EXPECT_EQ(upload(la.id), ResultClaim::proceed);
  EXPECT_EQ(s.job(j)->tiles.done, 1);
  EXPECT_EQ(s.job(j)->tiles.pending, 0);
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
}

TEST_F(SchedulerTest, AbandonedMergeKeepsTheTileWithTheLeaseThatUploadedIt) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id;
  const std::string b = s.register_worker("b").id;
  const Lease l = lease(a);
  ASSERT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  EXPECT_EQ(s.job(j)->tiles.leased, 1);
  now += 9'000;
  s.abandon_result(l.id);  // the merge failed on the coordinator's side; the worker retries its upload
  EXPECT_EQ(s.job(j)->tiles.leased, 1);
  EXPECT_EQ(s.job(j)->tiles.pending, 0);
  EXPECT_EQ(s.acquire(b).status, AcquireResult::no_work) << "the tile went to another worker while its upload retried";
  now += 9'000;  // a lease length from the abandon, not from the grant
  EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::ok);
  EXPECT_EQ(upload(l.id), ResultClaim::proceed);  // the retry is accepted
  EXPECT_EQ(s.job(j)->tiles.done, 1);
  EXPECT_THROW(s.finish_result(l.id), std::logic_error);
}

TEST_F(SchedulerTest, AbandonedMergeOfAnExpiredLeaseReturnsTheTile) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  now += 10'001;  // expired: the tile is pending, and a late upload may still claim it
  ASSERT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  s.abandon_result(l.id);
  EXPECT_EQ(s.job(j)->tiles.pending, 1);
  EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::gone);
  EXPECT_EQ(upload(l.id), ResultClaim::proceed);  // a retry is still accepted
  EXPECT_EQ(s.job(j)->tiles.done, 1);
}

TEST_F(SchedulerTest, ReleaseHandsTheTileBackWithoutAFailure) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  EXPECT_TRUE(s.release(l.id));
  EXPECT_TRUE(s.release(l.id));  // idempotent
  EXPECT_FALSE(s.release("l-none"));
  EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::gone);
  EXPECT_EQ(lease(a).tile, l.tile);
  EXPECT_EQ(s.counters().lease_expiries, 0u);
  // Releasing never blocklists, however often.
  for (int i = 0; i < 5; ++i) {
    const Lease again = s.acquire(a).lease;
    EXPECT_TRUE(s.release(again.id));
  }
  EXPECT_EQ(s.acquire(a).status, AcquireResult::granted);
  EXPECT_EQ(s.job(j)->state, JobState::running);
}

TEST_F(SchedulerTest, WorkerFailingTwiceIsBlocklistedForThatJobOnly) {
  const std::string j1 = job(5), j2 = job(0);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  Lease l = lease(a);
  ASSERT_EQ(l.job, j1);
  FailResult f = s.fail(l.id, "out of memory");
  EXPECT_EQ(f.status, FailResult::recorded);
  EXPECT_FALSE(f.blocklisted);
  l = lease(a);
  EXPECT_EQ(l.job, j1);
  EXPECT_EQ(l.tile, 0);  // the failed tile went back to pending and is the lowest
  f = s.fail(l.id, "out of memory");
  EXPECT_TRUE(f.blocklisted);
  EXPECT_FALSE(f.job_failed);
  // a skips j1 and gets j2; b still gets j1.
  EXPECT_EQ(lease(a).job, j2);
  EXPECT_EQ(lease(b).job, j1);
  // A second report on the same lease counts nothing.
  EXPECT_EQ(s.fail(l.id, "again").status, FailResult::recorded);
  EXPECT_EQ(s.job(j1)->state, JobState::running);
  EXPECT_EQ(s.fail("l-none", "x").status, FailResult::unknown);
}

TEST_F(SchedulerTest, TileFailingOnThreeWorkersFailsTheJobWithTheirErrors) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id, c = s.register_worker("c").id;
  // Two failures from one worker count once towards the three distinct workers.
  EXPECT_FALSE(s.fail(lease(a).id, "boom a1").job_failed);
  EXPECT_FALSE(s.fail(lease(b).id, "boom b").job_failed);
  EXPECT_EQ(s.job(j)->state, JobState::running);
  const Lease lc = lease(c);
  const FailResult f = s.fail(lc.id, "boom c");
  EXPECT_TRUE(f.job_failed);
  const JobStatus st = *s.job(j);
  EXPECT_EQ(st.state, JobState::failed);
  ASSERT_TRUE(st.error);
  EXPECT_NE(st.error->find("tile 0 failed on 3 workers"), std::string::npos) << *st.error;
  EXPECT_NE(st.error->find("boom a1"), std::string::npos);
  EXPECT_NE(st.error->find("boom b"), std::string::npos);
  EXPECT_NE(st.error->find("boom c"), std::string::npos);
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  EXPECT_EQ(upload(lc.id), ResultClaim::discarded);
  EXPECT_EQ(s.cancel(j).status, CancelResult::already_ended);
}

// Failures spread over different tiles blocklist every worker before any tile fails on three of them: the job must
// fail with their errors rather than wait forever.
TEST_F(SchedulerTest, JobFailsWhenEveryRegisteredWorkerIsBlocklisted) {
  const std::string j = job();  // 4 tiles
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id, c = s.register_worker("c").id;
  const Lease la = lease(a), lb = lease(b), lc = lease(c);  // tiles 0, 1, 2
  EXPECT_FALSE(s.fail(la.id, "err a").job_failed);
  EXPECT_FALSE(s.fail(lb.id, "err b").job_failed);
  EXPECT_FALSE(s.fail(lc.id, "err c").job_failed);
  // Second round, leased before any report so each worker gets another tile: c -> 0, a -> 1, b -> 2. Afterwards
  // every tile has failed on at most two workers and every worker twice.
  const Lease lc2 = lease(c), la2 = lease(a), lb2 = lease(b);
  ASSERT_EQ(lc2.tile, 0);
  ASSERT_EQ(la2.tile, 1);
  ASSERT_EQ(lb2.tile, 2);
  FailResult f = s.fail(la2.id, "err a2");
  EXPECT_TRUE(f.blocklisted);
  EXPECT_FALSE(f.job_failed);  // b and c can still work
  EXPECT_FALSE(s.fail(lb2.id, "err b2").job_failed);
  EXPECT_EQ(s.job(j)->state, JobState::running);
  f = s.fail(lc2.id, "err c2");
  EXPECT_TRUE(f.job_failed);
  const auto st = s.job(j);
  EXPECT_EQ(st->state, JobState::failed);
  ASSERT_TRUE(st->error.has_value());
  for (const char* text : {"blocklisted", "err a2", "err b2", "err c2"}) EXPECT_NE(st->error->find(text), std::string::npos) << *st->error;
}

// A worker that died or left (not seen for three lease lengths) no longer keeps a job alive: when every worker that is
// still present is blocklisted, the job fails, whether the last failure report or a lease request notices it.
TEST_F(SchedulerTest, WorkersNotSeenForAFewLeasesDoNotCountAgainstFailingTheJob) {
  const std::string j = job();  // 4 tiles, 10 s leases
  const std::string a = s.register_worker("a").id, gone = s.register_worker("gone").id;
  EXPECT_FALSE(s.fail(lease(a).id, "err 1").job_failed);
  EXPECT_FALSE(s.fail(lease(a).id, "err 2").job_failed);  // a blocklisted; "gone" was seen just now
  now += 29'000;
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  EXPECT_EQ(s.job(j)->state, JobState::running);  // 29 s < 3 leases: "gone" may still come back
  now += 2'000;
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  const auto st = s.job(j);
  EXPECT_EQ(st->state, JobState::failed);
  ASSERT_TRUE(st->error.has_value());
  EXPECT_NE(st->error->find("still present (1)"), std::string::npos) << *st->error;
  EXPECT_NE(st->error->find("err 2"), std::string::npos) << *st->error;

  // The same through a failure report: b stays in touch by heartbeats while a and c stay silent for 36 s.
  const std::string j2 = job();
  const std::string b = s.register_worker("b").id, c = s.register_worker("c").id;
  const Lease lb = lease(b);
  EXPECT_FALSE(s.fail(lease(b).id, "b 1").job_failed);
  for (int i = 0; i < 4; ++i) {
    now += 9'000;
    ASSERT_EQ(s.heartbeat(lb.id).status, HeartbeatResult::ok);
  }
  EXPECT_TRUE(s.fail(lb.id, "b 2").job_failed);  // a and c are registered but gone
  EXPECT_EQ(s.job(j2)->state, JobState::failed);
  (void)c;
}

TEST_F(SchedulerTest, SameWorkerFailingOneTileRepeatedlyDoesNotFailTheJob) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  s.fail(lease(a).id, "x");
  s.fail(lease(a).id, "y");  // a is now blocklisted
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  s.fail(lease(b).id, "z");
  EXPECT_EQ(s.job(j)->state, JobState::running);  // 2 distinct workers only
}

TEST_F(SchedulerTest, FailureOnExpiredLeaseCountsButDoesNotDisturbTheNewHolder) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  const Lease la = lease(a);
  now += 20'000;
  const Lease lb = lease(b);
  s.fail(la.id, "late");
  EXPECT_EQ(s.heartbeat(lb.id).status, HeartbeatResult::ok);
  EXPECT_EQ(s.job(j)->tiles.leased, 1);
}

TEST_F(SchedulerTest, CancelRevokesLeasesAndDiscardsUploads) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  const Lease l1 = lease(a), l2 = lease(a);
  const CancelResult c = s.cancel(j);
  EXPECT_EQ(c.status, CancelResult::cancelled);
  EXPECT_EQ(c.revoked_leases, 2);
  EXPECT_EQ(s.heartbeat(l1.id).status, HeartbeatResult::gone);
  EXPECT_EQ(s.check_result(l2.id).status, ResultClaim::discarded);
  EXPECT_EQ(upload(l2.id), ResultClaim::discarded);
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  const JobStatus st = *s.job(j);
  EXPECT_EQ(st.state, JobState::cancelled);
  EXPECT_EQ(st.finished_ms, now);
  EXPECT_EQ(s.cancel(j).status, CancelResult::already_ended);
  EXPECT_EQ(s.cancel("j-none").status, CancelResult::unknown);
  EXPECT_EQ(s.counters().active_leases, 0);
}

// Retry: a failed job goes back to the queue with its done tiles kept and its failures forgotten.
TEST_F(SchedulerTest, RetryOfAFailedJobLeasesOnlyTheTilesNotDone) {
  const std::string j = job();  // 4 tiles
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id, c = s.register_worker("c").id;
  EXPECT_EQ(upload(lease(a).id), ResultClaim::proceed);  // tile 0
  EXPECT_EQ(upload(lease(a).id), ResultClaim::proceed);  // tile 1
  EXPECT_FALSE(s.fail(lease(a).id, "boom a").job_failed);  // tile 2, a's first failure
  EXPECT_FALSE(s.fail(lease(b).id, "boom b").job_failed);
  EXPECT_TRUE(s.fail(lease(c).id, "boom c").job_failed);
  ASSERT_EQ(s.job(j)->state, JobState::failed);

  now += 1000;
  const RetryResult r = s.retry(j);
  EXPECT_EQ(r.status, RetryResult::retried);
  EXPECT_EQ(r.was, JobState::failed);
  EXPECT_EQ(r.pending, 2);
  JobStatus st = *s.job(j);
  EXPECT_EQ(st.state, JobState::running);
  EXPECT_FALSE(st.error);
  EXPECT_FALSE(st.finished_ms);
  EXPECT_EQ(st.tiles.done, 2);
  // c failed tile 2 before: no blocklist or failure count survives the retry, so three more failures are needed.
  const Lease l2 = lease(c), l3 = lease(c);
  EXPECT_EQ(l2.tile, 2);
  EXPECT_EQ(l3.tile, 3);
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);  // nothing else to render
  bool last = false;
  EXPECT_EQ(upload(l2.id, &last), ResultClaim::proceed);
  EXPECT_FALSE(last);
  EXPECT_EQ(upload(l3.id, &last), ResultClaim::proceed);
  EXPECT_TRUE(last);
  s.complete_job(j);
  EXPECT_EQ(s.job(j)->state, JobState::done);
  EXPECT_EQ(s.counters().tiles_rendered, 4u);
}

TEST_F(SchedulerTest, RetryOfACancelledJobRequeuesItAndRefusesOtherStates) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  EXPECT_EQ(s.retry(j).status, RetryResult::not_ended);
  EXPECT_EQ(s.cancel(j).status, CancelResult::cancelled);
  const RetryResult r = s.retry(j);
  EXPECT_EQ(r.status, RetryResult::retried);
  EXPECT_EQ(r.was, JobState::cancelled);
  EXPECT_EQ(r.pending, 4);
  EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::gone);  // the old lease stays revoked
  EXPECT_EQ(lease(a).tile, 0);
  EXPECT_EQ(s.retry("j-none").status, RetryResult::unknown);

  const std::string q = job();  // never started: queued again, not running
  EXPECT_EQ(s.cancel(q).status, CancelResult::cancelled);
  EXPECT_EQ(s.retry(q).status, RetryResult::retried);
  EXPECT_EQ(s.job(q)->state, JobState::queued);

  const std::string d = job(0, 64, 64, 64);
  const std::string b = s.register_worker("b").id;
  Lease ld;
  do ld = lease(b); while (ld.job != d);
  bool last = false;
  EXPECT_EQ(upload(ld.id, &last), ResultClaim::proceed);
  ASSERT_TRUE(last);
  s.complete_job(d);
  EXPECT_EQ(s.retry(d).status, RetryResult::done);
}

// Pause: a paused job gets no new leases, its running tiles finish and their uploads count.
TEST_F(SchedulerTest, PausedJobGetsNoNewLeasesButItsRunningTilesFinish) {
  const std::string hi = job(5);  // 4 tiles, leased first
  const std::string lo = job(0);
  const std::string a = s.register_worker("a").id;
  const Lease l0 = lease(a);
  ASSERT_EQ(l0.job, hi);
  const PauseResult p = s.pause(hi);
  EXPECT_EQ(p.status, PauseResult::changed);
  EXPECT_EQ(p.was, JobState::running);
  EXPECT_EQ(s.job(hi)->state, JobState::paused);
  EXPECT_EQ(lease(a).job, lo);  // the higher-priority job is skipped while paused
  now += 5000;
  EXPECT_EQ(s.heartbeat(l0.id).status, HeartbeatResult::ok);
  EXPECT_EQ(upload(l0.id), ResultClaim::proceed);
  EXPECT_EQ(s.job(hi)->tiles.done, 1);
  EXPECT_EQ(s.job(hi)->state, JobState::paused);
  EXPECT_EQ(s.pause(hi).status, PauseResult::wrong_state);  // already paused

  const PauseResult r = s.resume(hi);
  EXPECT_EQ(r.status, PauseResult::changed);
  EXPECT_EQ(r.was, JobState::paused);
  EXPECT_EQ(s.job(hi)->state, JobState::running);
  EXPECT_EQ(lease(a).job, hi);
  EXPECT_EQ(s.resume(hi).status, PauseResult::wrong_state);  // not paused
  EXPECT_EQ(s.pause("j-none").status, PauseResult::unknown);
  EXPECT_EQ(s.resume("j-none").status, PauseResult::unknown);
}

TEST_F(SchedulerTest, PauseOfAQueuedJobResumesQueuedAndEndedJobsCannotBePaused) {
  const std::string q = job();
  EXPECT_EQ(s.pause(q).status, PauseResult::changed);
  const std::string a = s.register_worker("a").id;
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  EXPECT_EQ(s.counters().jobs.at(JobState::paused), 1);
  EXPECT_EQ(s.resume(q).status, PauseResult::changed);
  EXPECT_EQ(s.job(q)->state, JobState::queued);  // it had never started
  EXPECT_EQ(s.pause(q).status, PauseResult::changed);
  EXPECT_EQ(s.cancel(q).status, CancelResult::cancelled);  // a paused job can be cancelled
  const PauseResult p = s.pause(q);
  EXPECT_EQ(p.status, PauseResult::wrong_state);
  EXPECT_EQ(p.was, JobState::cancelled);
  EXPECT_EQ(s.resume(q).status, PauseResult::wrong_state);
}

TEST_F(SchedulerTest, APausedJobWhoseLastTileLandsIsDone) {
  const std::string j = job(0, 64, 64, 64);  // one tile
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  EXPECT_EQ(s.pause(j).status, PauseResult::changed);
  bool last = false;
  EXPECT_EQ(upload(l.id, &last), ResultClaim::proceed);
  EXPECT_TRUE(last);
  s.complete_job(j);
  EXPECT_EQ(s.job(j)->state, JobState::done);
  EXPECT_EQ(s.pause(j).status, PauseResult::wrong_state);
}

// Priority change: the lease order follows the new priority at once; ended jobs keep theirs.
TEST_F(SchedulerTest, PriorityChangeReordersLeasesAndEndedJobsRefuseIt) {
  const std::string older = job(1), newer = job(0);
  const std::string a = s.register_worker("a").id;
  EXPECT_EQ(lease(a).job, older);
  const PriorityResult r = s.set_priority(newer, 5);
  EXPECT_EQ(r.status, PriorityResult::changed);
  EXPECT_EQ(s.job(newer)->params.priority, 5);
  EXPECT_EQ(lease(a).job, newer);
  EXPECT_EQ(s.set_priority(newer, -3).status, PriorityResult::changed);
  EXPECT_EQ(lease(a).job, older);  // back below the older job
  EXPECT_EQ(s.set_priority(older, -3).status, PriorityResult::changed);
  EXPECT_EQ(lease(a).job, older);  // equal priorities: the older job first

  EXPECT_EQ(s.pause(newer).status, PauseResult::changed);
  EXPECT_EQ(s.set_priority(newer, 9).status, PriorityResult::changed);  // a paused job may change it
  EXPECT_EQ(lease(a).job, older);
  EXPECT_EQ(s.cancel(newer).status, CancelResult::cancelled);
  const PriorityResult ended = s.set_priority(newer, 1);
  EXPECT_EQ(ended.status, PriorityResult::ended);
  EXPECT_EQ(ended.was, JobState::cancelled);
  EXPECT_EQ(s.job(newer)->params.priority, 9);
  EXPECT_EQ(s.set_priority("j-none", 1).status, PriorityResult::unknown);
}

// Raising the spp (server/job_refine.h): a done job runs again with every tile pending at the new spp; a running job's
// leases are revoked and their late uploads discarded; failed, cancelled and merging jobs refuse.
TEST_F(SchedulerTest, RaisingTheSppOfADoneJobLeasesEveryTileAgainAtTheNewSpp) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  for (int i = 0; i < 4; ++i) upload(lease(a).id);
  s.complete_job(j);
  ASSERT_EQ(s.job(j)->state, JobState::done);
  const RaiseResult r = s.raise_spp(j, 16);
  EXPECT_EQ(r.status, RaiseResult::raised);
  EXPECT_EQ(r.was, JobState::done);
  EXPECT_EQ(r.job.tiles.pending, 4);
  EXPECT_EQ(r.job.params.spp, 16u);
  const JobStatus st = *s.job(j);
  EXPECT_EQ(st.state, JobState::running);
  EXPECT_EQ(st.params.spp, 16u);
  EXPECT_EQ(st.tiles.done, 0);
  EXPECT_EQ(st.tiles.pending, 4);
  EXPECT_FALSE(st.finished_ms);
  bool last = false;
  for (int i = 0; i < 4; ++i) {
    const Lease l = lease(a);
    EXPECT_EQ(l.tile, i);
    EXPECT_EQ(l.spp, 16u);
    EXPECT_EQ(upload(l.id, &last), ResultClaim::proceed);
  }
  EXPECT_TRUE(last);
  s.complete_job(j);
  EXPECT_EQ(s.job(j)->state, JobState::done);
}

TEST_F(SchedulerTest, RaisingTheSppOfARunningJobRevokesItsLeasesAndDiscardsTheirUploads) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  const Lease done = lease(a), held = lease(a);
  upload(done.id);
  const RaiseResult r = s.raise_spp(j, 8);
  EXPECT_EQ(r.status, RaiseResult::raised);
  EXPECT_EQ(r.revoked_leases, 1);
  EXPECT_EQ(s.heartbeat(held.id).status, HeartbeatResult::gone);
  EXPECT_EQ(upload(held.id), ResultClaim::discarded);  // rendered at 4 spp: not merged into an 8 spp job
  EXPECT_EQ(s.job(j)->tiles.pending, 4);
  const Lease again = lease(a);
  EXPECT_EQ(again.tile, 0);
  EXPECT_EQ(again.spp, 8u);
  EXPECT_EQ(upload(again.id), ResultClaim::proceed);
}

TEST_F(SchedulerTest, RaisingTheSppIsRefusedForEndedOrMergingJobs) {
  const std::string j = job(), k = job();
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  ASSERT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  const RaiseResult merging = s.raise_spp(j, 8);
  EXPECT_EQ(merging.status, RaiseResult::merging);
  EXPECT_EQ(s.job(j)->params.spp, 4u);
  s.finish_result(l.id);
  EXPECT_EQ(s.raise_spp(j, 8).status, RaiseResult::raised);
  ASSERT_EQ(s.cancel(k).status, CancelResult::cancelled);
  const RaiseResult cancelled = s.raise_spp(k, 8);
  EXPECT_EQ(cancelled.status, RaiseResult::wrong_state);
  EXPECT_EQ(cancelled.was, JobState::cancelled);
  EXPECT_EQ(s.raise_spp("j-none", 8).status, RaiseResult::unknown);
  EXPECT_EQ(s.raise_spp(j, 8).status, RaiseResult::not_higher);  // already 8
  EXPECT_EQ(s.raise_spp(j, 6).status, RaiseResult::not_higher);
  ASSERT_EQ(s.pause(j).status, PauseResult::changed);
  EXPECT_EQ(s.raise_spp(j, 12).status, RaiseResult::raised);  // a paused job stays paused
  EXPECT_EQ(s.job(j)->state, JobState::paused);
}

// Workers: the list says what each one does; a drained worker finishes its tile and then gets no work.
TEST_F(SchedulerTest, WorkerListShowsStateLeaseTilesAndBlocklists) {
  const std::string j = job();
  const std::string a = s.register_worker("alpha", 8).id, b = s.register_worker("beta").id;
  std::vector<protocol::WorkerInfo> ws = s.workers();
  ASSERT_EQ(ws.size(), 2u);
  EXPECT_EQ(ws[0].id, a);
  EXPECT_EQ(ws[0].name, "alpha");
  EXPECT_EQ(ws[0].threads, 8);
  EXPECT_EQ(ws[0].state, protocol::WorkerState::idle);
  EXPECT_FALSE(ws[0].job);

  const Lease l = lease(a);
  ws = s.workers();
  EXPECT_EQ(ws[0].state, protocol::WorkerState::rendering);
  EXPECT_EQ(ws[0].job, j);
  EXPECT_EQ(ws[0].tile, l.tile);
  EXPECT_EQ(ws[0].rays, 0u);
  now += 2'000;
  EXPECT_EQ(upload(l.id), ResultClaim::proceed);
  EXPECT_FALSE(s.fail(lease(b).id, "boom 1").job_failed);
  EXPECT_FALSE(s.fail(lease(b).id, "boom 2").job_failed);  // b is now blocklisted for j
  ws = s.workers();
  EXPECT_EQ(ws[0].tiles_done, 1);
  EXPECT_EQ(ws[0].rays, 10u);  // the upload's (upload() sends 10)
  EXPECT_DOUBLE_EQ(ws[0].render_seconds, 2.0);
  EXPECT_EQ(ws[1].rays, 0u);  // failed tiles count for nothing
  EXPECT_EQ(ws[0].state, protocol::WorkerState::idle);
  EXPECT_EQ(ws[0].last_seen_ms, now);
  EXPECT_EQ(ws[1].blocklisted_for, std::vector<std::string>{j});
  EXPECT_TRUE(ws[0].blocklisted_for.empty());

  // Offline after three lease lengths (30 s here) without a request; back when it asks again.
  now += 30'001;
  EXPECT_EQ(s.workers()[1].state, protocol::WorkerState::offline);
  lease(a);
  EXPECT_EQ(s.workers()[0].state, protocol::WorkerState::rendering);
  EXPECT_EQ(s.workers()[1].state, protocol::WorkerState::offline);
}

TEST_F(SchedulerTest, ADrainedWorkerFinishesItsTileThenGetsNoWorkUntilUndrained) {
  const std::string j = job();
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  const std::optional<protocol::WorkerInfo> d = s.set_drained(a, true);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->state, protocol::WorkerState::draining);
  EXPECT_EQ(d->job, j);  // still rendering its tile
  EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::ok);
  EXPECT_EQ(upload(l.id), ResultClaim::proceed);  // its upload is accepted
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);  // though tiles are pending
  EXPECT_EQ(s.job(j)->tiles.pending, 3);
  EXPECT_EQ(s.workers()[0].state, protocol::WorkerState::draining);
  EXPECT_FALSE(s.workers()[0].job);
  now += 25'000;
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);  // polling keeps it seen, not offline
  EXPECT_EQ(s.workers()[0].state, protocol::WorkerState::draining);
  EXPECT_EQ(s.set_drained(a, false)->state, protocol::WorkerState::idle);
  EXPECT_EQ(lease(a).tile, 1);
  EXPECT_FALSE(s.set_drained("w-none", true));
}

TEST_F(SchedulerTest, TileDetailsCountAttemptsTimeRaysAndFailuresWithTheirLogLines) {
  const std::string j = job();  // 2x2 tiles
  const std::string a = s.register_worker("alpha").id, b = s.register_worker("beta").id;
  const Lease first = lease(a);  // tile 0
  ASSERT_EQ(first.tile, 0);
  now += 500;
  ASSERT_EQ(s.fail(first.id, "out of memory", {"line one", "line two"}).status, FailResult::recorded);
  const Lease second = lease(b);  // tile 0 again
  ASSERT_EQ(second.tile, 0);
  now += 1'000;
  ASSERT_EQ(s.heartbeat(second.id, 300).status, HeartbeatResult::ok);
  now += 1'500;
  ASSERT_EQ(upload(second.id), ResultClaim::proceed);  // 10 more rays with the upload
  const Lease third = lease(b);  // tile 1, still leased

  const auto tiles = s.tiles(j);
  ASSERT_TRUE(tiles);
  EXPECT_EQ(tiles->job, j);
  ASSERT_EQ(tiles->tiles.size(), 4u);
  const protocol::TileInfo& t0 = tiles->tiles[0];
  EXPECT_EQ(t0.state, "done");
  EXPECT_EQ(t0.window, (PixelWindow{0, 0, 64, 64}));
  EXPECT_EQ(t0.attempts, 2);
  ASSERT_TRUE(t0.render_seconds);
  EXPECT_DOUBLE_EQ(*t0.render_seconds, 2.5);  // the accepted lease's grant to its upload
  EXPECT_EQ(t0.rays, 310u);
  EXPECT_FALSE(t0.worker);
  EXPECT_EQ(t0.rendered_by, b);  // the worker whose result was accepted, not the one that failed
  EXPECT_EQ(t0.rendered_by_name, "beta");
  ASSERT_EQ(t0.failures.size(), 1u);
  EXPECT_EQ(t0.failures[0].worker, a);
  EXPECT_EQ(t0.failures[0].worker_name, "alpha");
  EXPECT_EQ(t0.failures[0].error, "out of memory");
  EXPECT_EQ(t0.failures[0].log, (std::vector<std::string>{"line one", "line two"}));
  const protocol::TileInfo& t1 = tiles->tiles[1];
  EXPECT_EQ(t1.state, "leased");
  EXPECT_EQ(t1.worker, b);
  EXPECT_EQ(t1.worker_name, "beta");
  EXPECT_EQ(t1.attempts, 1);
  EXPECT_FALSE(t1.render_seconds);
  EXPECT_FALSE(t1.rendered_by);
  EXPECT_EQ(tiles->tiles[3].attempts, 0);
  EXPECT_EQ(tiles->tiles[3].state, "pending");
  EXPECT_FALSE(s.tiles("j-nobody"));
  (void)third;
}

// Uploads the lease's result with `log` (claim, finish).
void upload_with_log(Scheduler& s, const std::string& lease, std::vector<std::string> log) {
  ASSERT_EQ(s.claim_result(lease).status, ResultClaim::proceed);
  s.finish_result(lease, 1, {}, std::move(log));
}

TEST_F(SchedulerTest, ADoneTileKeepsTheLogSentWithItsUploadUntilItIsRenderedAgain) {
  const std::string j = job();  // 4 tiles
  const std::string w = s.register_worker("a").id;
  upload_with_log(s, lease(w).id, {"leased window", "rendered in 0.5s"});
  upload_with_log(s, lease(w).id, {});  // a worker that sends no log
  const Lease third = lease(w);
  auto tiles = s.tiles(j);
  ASSERT_TRUE(tiles);
  EXPECT_EQ(tiles->tiles[0].log, (std::vector<std::string>{"leased window", "rendered in 0.5s"}));
  EXPECT_FALSE(tiles->tiles[0].log_not_kept);
  EXPECT_TRUE(tiles->tiles[1].log.empty());
  EXPECT_FALSE(tiles->tiles[1].log_not_kept);  // none came: none was dropped
  EXPECT_TRUE(tiles->tiles[2].log.empty());    // leased
  EXPECT_EQ(tiles->logs_not_kept, 0);
  // Requeued, its log goes with its render; rendered again, it has the new one.
  EXPECT_EQ(s.requeue(j, 0).status, RequeueResult::requeued);
  EXPECT_TRUE(s.tiles(j)->tiles[0].log.empty());
  upload_with_log(s, third.id, {"third"});
  upload_with_log(s, lease(w).id, {"again"});
  EXPECT_EQ(s.tiles(j)->tiles[0].log, (std::vector<std::string>{"again"}));
}

TEST(SchedulerTileLogs, AJobKeepsTileLogsUpToItsBoundAndCountsTheTilesWhoseLogWasNotKept) {
  int64_t now = 1'000'000;
  SchedulerConfig config{10'000, 3, 2, ""};
  config.job_tile_log_bytes = 10;
  Scheduler s{config, [&now] { return now; }};
  JobParams p;
  p.width = 128;
  p.height = 128;
  p.tile_size = 64;
  p.spp = 1;
  p.scene_hash = "abc";
  const std::string j = s.add_job(p), k = s.add_job(p);
  const std::string w = s.register_worker("a").id;
  const auto next = [&] { return s.acquire(w).lease.id; };
  upload_with_log(s, next(), {"12345", "678"});  // 8 bytes: kept
  upload_with_log(s, next(), {"123"});           // 11 in all: not kept
  upload_with_log(s, next(), {"12"});            // 10 in all: kept
  upload_with_log(s, next(), {"1"});             // 11: not kept
  auto tiles = s.tiles(j);
  ASSERT_TRUE(tiles);
  EXPECT_EQ(tiles->tiles[0].log.size(), 2u);
  EXPECT_TRUE(tiles->tiles[1].log.empty());
  EXPECT_TRUE(tiles->tiles[1].log_not_kept);
  EXPECT_EQ(tiles->tiles[2].log, (std::vector<std::string>{"12"}));
  EXPECT_TRUE(tiles->tiles[3].log_not_kept);
  EXPECT_EQ(tiles->logs_not_kept, 2);
  // The bound is per job: the next job keeps its own.
  upload_with_log(s, next(), {"0123456789"});
  EXPECT_EQ(s.tiles(k)->tiles[0].log.size(), 1u);
  EXPECT_EQ(s.tiles(k)->logs_not_kept, 0);
  // Rendering a tile again frees what its log took, and forgets that one was not kept.
  EXPECT_EQ(s.requeue(k, 0).status, RequeueResult::requeued);
  upload_with_log(s, next(), {"0123456789"});
  EXPECT_EQ(s.tiles(k)->tiles[0].log.size(), 1u);
  upload_with_log(s, next(), {"x"});  // 11 bytes in all
  EXPECT_EQ(s.tiles(k)->logs_not_kept, 1);
  ASSERT_EQ(s.requeue(k, 1).status, RequeueResult::requeued);
  EXPECT_EQ(s.tiles(k)->logs_not_kept, 0);
}

TEST_F(SchedulerTest, RequeueRendersADoneOrLeasedTileAgainAndRefusesOtherStates) {
  const std::string j = job();  // 4 tiles
  const std::string w = s.register_worker("a").id;
  EXPECT_EQ(s.requeue(j, 0).status, RequeueResult::wrong_job_state);  // queued: nothing rendered yet
  const Lease l0 = lease(w);
  ASSERT_EQ(upload(l0.id), ResultClaim::proceed);
  const Lease l1 = lease(w);
  EXPECT_EQ(s.requeue(j, 2).status, RequeueResult::wrong_tile_state);  // pending, never failed
  EXPECT_EQ(s.requeue(j, 4).status, RequeueResult::no_tile);
  EXPECT_EQ(s.requeue(j, -1).status, RequeueResult::no_tile);
  EXPECT_EQ(s.requeue("j-nobody", 0).status, RequeueResult::unknown);

  const RequeueResult done = s.requeue(j, 0);
  EXPECT_EQ(done.status, RequeueResult::requeued);
  EXPECT_EQ(done.was, TileState::done);
  EXPECT_EQ(s.job(j)->tiles.done, 0);
  EXPECT_FALSE(s.tiles(j)->tiles[0].rendered_by);  // no longer rendered by anyone
  const RequeueResult leased = s.requeue(j, 1);
  EXPECT_EQ(leased.status, RequeueResult::requeued);
  EXPECT_TRUE(leased.revoked);
  EXPECT_EQ(s.heartbeat(l1.id).status, HeartbeatResult::gone);  // the worker abandons it
  EXPECT_EQ(lease(w).tile, 0);  // rendered again, lowest first
  EXPECT_EQ(lease(w).tile, 1);
  EXPECT_EQ(s.tiles(j)->tiles[0].attempts, 2);

  const Lease bad = lease(w);  // tile 2 fails once: a failed pending tile can be requeued (its failures forgotten)
  s.fail(bad.id, "boom");
  EXPECT_EQ(s.requeue(j, bad.tile).status, RequeueResult::requeued);
  EXPECT_TRUE(s.tiles(j)->tiles[size_t(bad.tile)].failures.empty());
  s.cancel(j);
  EXPECT_EQ(s.requeue(j, 0).status, RequeueResult::wrong_job_state);
}

TEST_F(SchedulerTest, ALeaseOlderThanTheTileTimeoutIsRevokedAsAFailureEvenWithHeartbeats) {
  JobParams p;
  p.width = 64;
  p.height = 64;
  p.tile_size = 64;  // one tile
  p.tile_timeout_seconds = 25;
  const std::string j = s.add_job(p);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id, c = s.register_worker("c").id;
  for (const std::string& w : {a, b, c}) {
    EXPECT_FALSE(s.job(j)->finished());  // fewer than 3 workers failed the tile so far
    const Lease l = lease(w);
    for (int i = 0; i < 5; ++i) {  // heartbeats every 5 s keep the 10 s lease alive, but not past 25 s since grant
      now += 5'000;
      EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::ok);
    }
    now += 1;
    EXPECT_EQ(s.heartbeat(l.id).status, HeartbeatResult::gone);  // the worker abandons the tile
    const auto tiles = s.tiles(j);
    ASSERT_EQ(tiles->tiles[0].state, "pending");
    const auto& failures = tiles->tiles[0].failures;
    const auto mine = std::find_if(failures.begin(), failures.end(), [&](const auto& f) { return f.worker == w; });
    ASSERT_NE(mine, failures.end());
    EXPECT_EQ(mine->error, "tile timed out after 25 s");
  }
  const auto st = s.job(j);
  EXPECT_EQ(st->state, JobState::failed);  // the tile failed on 3 workers
  EXPECT_NE(st->error->find("tile timed out after 25 s"), std::string::npos);
}

TEST_F(SchedulerTest, EachLeaseExpiresOrTimesOutOnTimeWhateverTheOtherLeasesDo) {
  JobParams p;
  p.width = 64;
  p.height = 64;
  p.tile_size = 64;  // one tile per job
  const std::string slow = s.add_job(p);  // the default tile timeout (an hour)
  const std::string w = s.register_worker("a").id, v = s.register_worker("b").id;
  const Lease a = lease(w);  // at t: lease until t + 10 s
  now += 5'000;
  EXPECT_EQ(s.heartbeat(a.id).status, HeartbeatResult::ok);  // until t + 15 s
  p.tile_timeout_seconds = 2;
  const std::string quick = s.add_job(p);
  const Lease b = lease(v);  // at t + 5 s, timed out after t + 7 s: earlier than anything the first lease needs
  EXPECT_EQ(b.job, quick);
  now += 2'000;
  EXPECT_EQ(s.heartbeat(b.id).status, HeartbeatResult::ok);
  now += 1;
  EXPECT_EQ(s.heartbeat(b.id).status, HeartbeatResult::gone);
  EXPECT_EQ(s.tiles(quick)->tiles[0].state, "pending");
  EXPECT_EQ(s.heartbeat(a.id).status, HeartbeatResult::ok);  // until t + 17.001 s
  now += 10'000;
  EXPECT_EQ(s.tiles(slow)->tiles[0].state, "leased");
  now += 1;
  EXPECT_EQ(s.tiles(slow)->tiles[0].state, "pending");  // expired, seen by an operation that is not about it
  EXPECT_EQ(s.heartbeat(a.id).status, HeartbeatResult::gone);
}

TEST_F(SchedulerTest, CancelQueuedJob) {
  const std::string j = job();
  EXPECT_EQ(s.cancel(j).status, CancelResult::cancelled);
  const std::string a = s.register_worker("a").id;
  EXPECT_EQ(s.acquire(a).status, AcquireResult::no_work);
  EXPECT_FALSE(s.job(j)->started_ms);
}

TEST_F(SchedulerTest, CancelDuringMergeNeverCompletes) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id;
  const Lease l = lease(a);
  ASSERT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  s.cancel(j);
  EXPECT_FALSE(s.finish_result(l.id).last);
  s.complete_job(j);
  EXPECT_EQ(s.job(j)->state, JobState::cancelled);
}

TEST_F(SchedulerTest, FailJobAfterWriteError) {
  const std::string j = job(0, 64, 64, 64);
  const std::string a = s.register_worker("a").id;
  ASSERT_EQ(upload(lease(a).id), ResultClaim::proceed);
  s.fail_job(j, "writing result.exr: disk full");
  EXPECT_EQ(s.job(j)->state, JobState::failed);
  EXPECT_EQ(*s.job(j)->error, "writing result.exr: disk full");
}

TEST_F(SchedulerTest, CountersByState) {
  const std::string a = job(), b = job();
  s.cancel(a);
  const SchedulerCounters c = s.counters();
  EXPECT_EQ(c.jobs.at(JobState::queued), 1);
  EXPECT_EQ(c.jobs.at(JobState::cancelled), 1);
  EXPECT_EQ(c.jobs.at(JobState::running), 0);
  (void)b;
}

TEST_F(SchedulerTest, RejectsBadJobs) {
  EXPECT_THROW(job(0, 0, 10, 4), std::invalid_argument);
  EXPECT_THROW(job(0, 10, 10, 0), std::invalid_argument);
}

TEST(SchedulerIds, CarryTheTag) {
  Scheduler s{SchedulerConfig{1000, 3, 2, "x7"}, [] { return int64_t(0); }};
  const std::string w = s.register_worker("a").id;
  EXPECT_EQ(w.rfind("w-x7-", 0), 0u) << w;
}


// An 8x4 job of two 4-pixel tiles at 1 spp.
JobParams two_tile_job() {
  JobParams p;
  p.width = 8;
  p.height = 4;
  p.tile_size = 4;
  p.spp = 1;
  return p;
}

// A store whose flushes the test completes: sync_async keeps each continuation until flush_all().
struct DeferredFlushStore final : SchedulerStore {
  std::vector<std::function<void()>> waiting;
  void apply(const SchedulerChanges&) override {}
  SchedulerSnapshot load() override { return {}; }
  void sync_async(std::function<void()> then) override { waiting.push_back(std::move(then)); }
  void flush_all() {
    std::vector<std::function<void()>> now;
    now.swap(waiting);
    for (auto& f : now) f();
  }
};

TEST(SchedulerFlush, ADoneTileIsAcknowledgedAndCountedOnlyOnceItsFlushReturned) {
  DeferredFlushStore store;
  int64_t now = 1'000;
  Scheduler s(SchedulerConfig{10'000, 3, 2, "f"}, [&] { return now; }, store);
  const std::string w = s.register_worker("w").id;
  const std::string j = s.add_job(two_tile_job());
  store.flush_all();
  const std::string pixels(4 * 4 * 3 * sizeof(float), '\0');
  const Lease l0 = s.acquire(w).lease;
  ASSERT_EQ(s.claim_result(l0.id).status, ResultClaim::proceed);
  std::optional<FinishResult> acked;
  s.finish_result(l0.id, 0, pixels, {}, [&](FinishResult r) { acked = r; });
  EXPECT_FALSE(acked) << "acknowledged before the flush";
  JobStatus st = *s.job(j);
  EXPECT_EQ(st.tiles.done, 0) << "an unflushed tile counted as done";
  EXPECT_EQ(st.tiles.leased, 1);
  EXPECT_EQ(s.tiles(j)->tiles[0].state, "merging");
  // A repeat of the upload is a duplicate, and its answer waits for the same flush.
  EXPECT_EQ(s.check_result(l0.id).status, ResultClaim::duplicate);
  bool duplicate_acked = false;
  s.after_sync([&] { duplicate_acked = true; });
  EXPECT_FALSE(duplicate_acked);
  store.flush_all();
  ASSERT_TRUE(acked);
  EXPECT_FALSE(acked->last);
  EXPECT_TRUE(duplicate_acked);
  st = *s.job(j);
  EXPECT_EQ(st.tiles.done, 1);
  EXPECT_EQ(s.tiles(j)->tiles[0].state, "done");

  const Lease l1 = s.acquire(w).lease;
  ASSERT_EQ(s.claim_result(l1.id).status, ResultClaim::proceed);
  acked.reset();
  s.finish_result(l1.id, 0, pixels, {}, [&](FinishResult r) { acked = r; });
  EXPECT_FALSE(acked);
  store.flush_all();
  ASSERT_TRUE(acked);
  EXPECT_TRUE(acked->last) << "the job's last tile, once durable, finishes it";
}

TEST(SchedulerFlush, ARequeuedUnflushedTileIsCountedOnce) {
  DeferredFlushStore store;
  int64_t now = 1'000;
  Scheduler s(SchedulerConfig{10'000, 3, 2, "r"}, [&] { return now; }, store);
  const std::string w = s.register_worker("w").id;
  const std::string j = s.add_job(two_tile_job());
  const Lease l0 = s.acquire(w).lease;
  ASSERT_EQ(s.claim_result(l0.id).status, ResultClaim::proceed);
  bool acked = false;
  s.finish_result(l0.id, 0, std::string(4 * 4 * 3 * sizeof(float), '\0'), {}, [&](FinishResult) { acked = true; });
  ASSERT_EQ(s.requeue(j, 0).status, RequeueResult::requeued);
  store.flush_all();
  EXPECT_TRUE(acked);
  const JobStatus st = *s.job(j);
  EXPECT_EQ(st.tiles.done, 0);
  EXPECT_EQ(st.tiles.pending + st.tiles.leased + st.tiles.done, st.tiles.total);
}

}  // namespace
}  // namespace tessera::server

namespace tessera::server {
namespace {

// A sequence of 64x64 frames (one 64-pixel tile each) numbered `numbers`, frame k at spp k.
std::string sequence(Scheduler& s, const std::vector<int64_t>& numbers,
                     protocol::FrameOrder order = protocol::FrameOrder::in_order) {
  JobParams p;
  p.tile_size = 32;  // 4 tiles a frame
  p.frame_order = order;
  std::vector<FrameParams> frames;
  for (const int64_t n : numbers) frames.push_back({n, 64, 64, uint32_t(n), "hash-" + std::to_string(n)});
  return s.add_sequence(p, frames);
}

TEST_F(SchedulerTest, ASequencesFramesAreLeasedInOrderEachWithItsOwnSppAndScene) {
  EXPECT_THROW(sequence(s, {1, 3, 2}), std::invalid_argument);  // frames come in number order
  EXPECT_THROW(sequence(s, {1, 1}), std::invalid_argument);
  EXPECT_TRUE(s.jobs().empty());
  const std::string seq = sequence(s, {1, 2, 3});
  const std::string w = s.register_worker("a").id;
  for (const int64_t frame : {1, 2, 3})
    for (int tile = 0; tile < 4; ++tile) {
      const Lease l = lease(w);
      EXPECT_EQ(l.job, frame_job_id(seq, frame));
      EXPECT_EQ(l.spp, uint32_t(frame));
      EXPECT_EQ(l.scene_hash, "hash-" + std::to_string(frame));
      EXPECT_EQ(l.tile, tile);
    }
  const JobStatus st = *s.job(seq);
  EXPECT_EQ(st.state, JobState::running);
  EXPECT_EQ(st.tiles.total, 12);
  EXPECT_EQ(st.tiles.leased, 12);
  EXPECT_EQ(st.frames->total, 3);
  EXPECT_EQ(st.frames->first, 1);
  EXPECT_EQ(st.frames->last, 3);
  EXPECT_EQ(s.jobs().size(), 1u);  // frames are not listed
}

TEST_F(SchedulerTest, ASequencesStateFollowsItsFramesAndRetryTakesChosenFrames) {
  const std::string seq = sequence(s, {1, 2, 3});
  const std::string w = s.register_worker("a").id;
  EXPECT_EQ(s.job(seq)->state, JobState::queued);
  for (int tile = 0; tile < 4; ++tile) upload(lease(w).id);  // frame 1 rendered
  s.complete_job(frame_job_id(seq, 1));
  s.fail_job(frame_job_id(seq, 2), "broken");
  EXPECT_EQ(s.job(seq)->state, JobState::running);  // frame 3 is still to render
  EXPECT_EQ(s.cancel(seq).status, CancelResult::cancelled);
  JobStatus st = *s.job(seq);
  EXPECT_EQ(st.state, JobState::failed);  // every frame ended, one failed
  EXPECT_EQ(st.frames->done, 1);
  EXPECT_EQ(st.frames->failed, 1);
  EXPECT_EQ(st.frames->cancelled, 1);
  EXPECT_NE(st.error->find("frame 2: broken"), std::string::npos) << *st.error;
  EXPECT_EQ(s.retry(seq, {7}).status, RetryResult::no_frame);
  EXPECT_EQ(s.retry(seq, {1}).status, RetryResult::done);
  const RetryResult r = s.retry(seq, {3});
  ASSERT_EQ(r.status, RetryResult::retried);
  EXPECT_EQ(r.jobs, std::vector<std::string>{frame_job_id(seq, 3)});
  EXPECT_EQ(r.pending, 4);
  for (int tile = 0; tile < 4; ++tile) EXPECT_EQ(lease(w).job, frame_job_id(seq, 3));  // only frame 3's tiles
  EXPECT_EQ(s.acquire(w).status, AcquireResult::no_work);
}

TEST_F(SchedulerTest, FramesInAnyOrderKeepEachWorkerOnAFrameOfItsOwn) {
  const std::string seq = sequence(s, {1, 2, 3}, protocol::FrameOrder::any);
  const std::string a = s.register_worker("a").id, b = s.register_worker("b").id;
  EXPECT_EQ(lease(a).job, frame_job_id(seq, 1));
  EXPECT_EQ(lease(b).job, frame_job_id(seq, 2));  // not a's frame
  for (int i = 0; i < 3; ++i) EXPECT_EQ(lease(a).job, frame_job_id(seq, 1));
  EXPECT_EQ(lease(a).job, frame_job_id(seq, 3));  // its frame has no tile left: an untouched one
  for (int i = 0; i < 3; ++i) EXPECT_EQ(lease(b).job, frame_job_id(seq, 2));
  EXPECT_EQ(lease(b).job, frame_job_id(seq, 3));  // nothing untouched left: shares a's
}

}  // namespace
}  // namespace tessera::server
