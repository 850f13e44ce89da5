// Jobs that wait for other jobs: a chain waits, a failure blocks it with the reason, a retry releases it; sequences
// wait frame by frame; refusals at submission; purges that would strand a held job; a restart keeps it all.
#include "server/database.h"
#include "server/scheduler.h"

#include "tests/support/test_files.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

// A scheduler on a manual clock over a DurableStore in a fresh folder; one-tile jobs (64x64 at tile size 64).
struct DependencyTest : ::testing::Test {
  fs::path dir;
  int64_t now = 2'000'000;
  std::unique_ptr<DurableStore> store;
  std::unique_ptr<Scheduler> s;
  std::string worker;

  void SetUp() override {
    dir = fs::temp_directory_path() / ("tessera-deps-test-" + random_hex(6));
    open();
  }
  void TearDown() override {
    s.reset();
    store.reset();
    fs::remove_all(dir);
  }
  void open() {
    store = std::make_unique<DurableStore>(dir, Durability::process);
    s = std::make_unique<Scheduler>(SchedulerConfig{10'000, 1, 1, ""}, [this] { return now; }, *store);
    worker = s->register_worker("w").id;
  }
  void reopen() {
    s.reset();
    store.reset();
    open();
  }
  static JobParams params(std::vector<std::string> after = {}, bool per_frame = false) {
    JobParams p;
    p.width = 64;
    p.height = 64;
    p.tile_size = 64;
    p.spp = 1;
    p.scene_hash = "h";
    p.pipeline.after = std::move(after);
    p.pipeline.per_frame = per_frame;
    return p;
  }
  std::string job(std::vector<std::string> after = {}) { return s->add_job(params(std::move(after))); }
  std::string sequence(std::vector<int64_t> numbers, std::vector<std::string> after = {}, bool per_frame = false) {
    std::vector<FrameParams> frames;
    for (const int64_t n : numbers) frames.push_back({n, 64, 64, 1, "h" + std::to_string(n)});
    return s->add_sequence(params(std::move(after), per_frame), frames);
  }
  JobStatus status(const std::string& id) { return *s->job(id); }
  // Leases the next tile; its job, or "" when there is no work.
  std::string next_job() {
    const AcquireResult r = s->acquire(worker);
    if (r.status != AcquireResult::granted) return "";
    s->release(r.lease.id);
    return r.lease.job;
  }
  // Renders the job's single tile and completes it.
  void finish(const std::string& id) {
    s->set_priority(id, 100);  // its tile comes first
    const AcquireResult r = s->acquire(worker);
    ASSERT_EQ(r.status, AcquireResult::granted);
    ASSERT_EQ(r.lease.job, id);
    ASSERT_EQ(s->claim_result(r.lease.id).status, ResultClaim::proceed);
    ASSERT_TRUE(s->finish_result(r.lease.id, 1, std::string(64 * 64 * 12, '\0')).last);
    s->complete_job(id);
    ASSERT_EQ(status(id).state, JobState::done);
  }
};

TEST_F(DependencyTest, AChainWaitsIsBlockedByAFailureAndReleasedByTheRetry) {
  const std::string a = job(), b = job({a}), c = job({b});
  EXPECT_EQ(status(a).state, JobState::queued);
  EXPECT_EQ(status(b).state, JobState::waiting);
  EXPECT_EQ(status(b).reason, "waiting for " + a);
  EXPECT_EQ(status(c).state, JobState::waiting);
  EXPECT_EQ(status(c).reason, "waiting for " + b);
  EXPECT_EQ(status(a).dependents, std::vector<std::string>{b});
  EXPECT_EQ(status(b).params.pipeline.after, std::vector<std::string>{a});
  EXPECT_EQ(s->leasable_tiles(worker), 1);  // only a's tile
  EXPECT_EQ(next_job(), a);

  // a fails (its one tile failed on the one worker the config asks for): b and c are blocked, saying why.
  const AcquireResult l = s->acquire(worker);
  ASSERT_EQ(l.lease.job, a);
  EXPECT_TRUE(s->fail(l.lease.id, "out of memory").job_failed);
  EXPECT_EQ(status(a).state, JobState::failed);
  EXPECT_EQ(status(b).state, JobState::blocked);
  EXPECT_EQ(status(b).reason, "dependency " + a + " failed: " + *status(a).error);
  EXPECT_NE(status(b).reason->find("out of memory"), std::string::npos);
  EXPECT_EQ(status(c).state, JobState::blocked);
  EXPECT_EQ(status(c).reason, "dependency " + b + " is blocked: " + *status(b).reason);
  EXPECT_EQ(next_job(), "");

  // Retrying a puts b and c back to waiting; a done releases b alone, b done releases c.
  ASSERT_EQ(s->retry(a).status, RetryResult::retried);
  EXPECT_EQ(status(b).state, JobState::waiting);
  EXPECT_EQ(status(b).reason, "waiting for " + a);
  EXPECT_EQ(status(c).state, JobState::waiting);
  finish(a);
  EXPECT_EQ(status(b).state, JobState::queued);
  EXPECT_FALSE(status(b).reason);
  EXPECT_EQ(status(c).state, JobState::waiting);
  finish(b);
  EXPECT_EQ(status(c).state, JobState::queued);
  finish(c);
}

TEST_F(DependencyTest, ACancelledDependencyBlocksAndADependentCancelledWhileWaitingEnds) {
  const std::string a = job(), b = job({a}), c = job({a});
  ASSERT_EQ(s->cancel(a).status, CancelResult::cancelled);
  EXPECT_EQ(status(b).state, JobState::blocked);
  EXPECT_EQ(status(b).reason, "dependency " + a + " was cancelled");
  ASSERT_EQ(s->cancel(c).status, CancelResult::cancelled);
  EXPECT_FALSE(status(c).reason);
  // A retried dependent that still waits goes back to waiting, not to the queue.
  ASSERT_EQ(s->retry(a).status, RetryResult::retried);
  ASSERT_EQ(s->retry(c).status, RetryResult::retried);
  EXPECT_EQ(status(c).state, JobState::waiting);
  EXPECT_EQ(status(b).state, JobState::waiting);
  finish(a);
  EXPECT_EQ(status(b).state, JobState::queued);
  EXPECT_EQ(status(c).state, JobState::queued);
}

TEST_F(DependencyTest, AJobWhoseDependenciesAreDoneOrEndedStartsAccordingly) {
  const std::string a = job();
  finish(a);
  EXPECT_EQ(status(job({a})).state, JobState::queued);
  const std::string f = job();
  s->fail_job(f, "broken scene");
  const JobStatus b = status(job({a, f}));
  EXPECT_EQ(b.state, JobState::blocked);
  EXPECT_EQ(b.reason, "dependency " + f + " failed: broken scene");
}

TEST_F(DependencyTest, UnknownIdsAndCyclesAreRefusedWithASentence) {
  const std::string a = job();
  try {
    job({a, "j-404", "j-405"});
    FAIL() << "accepted unknown dependencies";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "cannot wait for j-404, j-405: no such jobs on this coordinator");
  }
  const std::string id = s->new_job_id();
  try {
    s->add_job(params({id}), id);
    FAIL() << "accepted a job waiting for itself";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "job " + id + " cannot wait for " + id + ": " + id +
                                         " is the job itself, a cycle that would never start");
  }
  EXPECT_FALSE(s->job(id));
  EXPECT_EQ(status(a).dependents, std::vector<std::string>{});
}

TEST_F(DependencyTest, PerFrameDependenciesReleaseFrameByFrame) {
  const std::string a = sequence({1, 2, 3});
  const std::string b = sequence({1, 2, 3}, {a}, true);
  const std::string whole = sequence({1, 2}, {a});
  EXPECT_EQ(status(b).state, JobState::waiting);
  EXPECT_EQ(status(b).frames->waiting, 3);
  EXPECT_EQ(status(b).reason, "frame 1: waiting for " + frame_job_id(a, 1));
  EXPECT_EQ(status(frame_job_id(b, 2)).params.pipeline.after, std::vector<std::string>{frame_job_id(a, 2)});
  EXPECT_EQ(status(a).dependents, (std::vector<std::string>{b, whole}));
  EXPECT_EQ(status(frame_job_id(a, 2)).dependents, std::vector<std::string>{frame_job_id(b, 2)});
  // Frame 2 of a first: frame 2 of b may start, the others wait; the sequence waiting for all of a waits on.
  finish(frame_job_id(a, 2));
  EXPECT_EQ(status(frame_job_id(b, 2)).state, JobState::queued);
  EXPECT_EQ(status(frame_job_id(b, 1)).state, JobState::waiting);
  EXPECT_EQ(status(b).state, JobState::queued);
  EXPECT_EQ(status(whole).state, JobState::waiting);
  // A failed frame blocks its own frame only.
  s->fail_job(frame_job_id(a, 3), "bad frame");
  EXPECT_EQ(status(frame_job_id(b, 3)).state, JobState::blocked);
  EXPECT_EQ(status(frame_job_id(b, 1)).state, JobState::waiting);
  EXPECT_EQ(status(whole).state, JobState::waiting);  // a is not over yet
  finish(frame_job_id(a, 1));
  EXPECT_EQ(status(whole).state, JobState::blocked);  // a failed (one of its frames did)
  EXPECT_EQ(status(whole).reason, "frame 1: dependency " + a + " failed");
  ASSERT_EQ(s->retry(a).status, RetryResult::retried);
  EXPECT_EQ(status(whole).state, JobState::waiting);
  EXPECT_EQ(status(frame_job_id(b, 3)).state, JobState::waiting);
  finish(frame_job_id(b, 2));
  finish(frame_job_id(b, 1));
  finish(frame_job_id(a, 3));
  EXPECT_EQ(status(whole).state, JobState::queued);
}

// The worked example of docs/protocol.md, "Dependencies", row by row.
TEST_F(DependencyTest, TheProtocolsWorkedExample) {
  const std::string a = sequence({1, 2, 3}), b = sequence({1, 2, 3}, {a}, true), c = job({b});
  const auto f = [](const std::string& seq, int64_t n) { return frame_job_id(seq, n); };
  EXPECT_EQ(status(b).state, JobState::waiting);
  EXPECT_EQ(status(b).reason, "frame 1: waiting for " + f(a, 1));
  EXPECT_EQ(status(c).reason, "waiting for " + b);
  finish(f(a, 1));
  EXPECT_EQ(status(a).state, JobState::running);
  EXPECT_EQ(status(f(b, 1)).state, JobState::queued);
  EXPECT_EQ(status(f(b, 2)).state, JobState::waiting);
  s->fail_job(f(a, 2), "boom");
  EXPECT_EQ(status(a).state, JobState::running);
  EXPECT_EQ(status(f(b, 2)).reason, "dependency " + f(a, 2) + " failed: boom");
  EXPECT_EQ(status(c).state, JobState::waiting);
  finish(f(a, 3));
  EXPECT_EQ(status(a).state, JobState::failed);
  finish(f(b, 1));
  finish(f(b, 3));
  EXPECT_EQ(status(b).state, JobState::blocked);
  EXPECT_EQ(status(b).reason, "frame 2: dependency " + f(a, 2) + " failed: boom");
  EXPECT_EQ(status(c).state, JobState::blocked);
  EXPECT_EQ(status(c).reason, "dependency " + b + " is blocked: frame 2: dependency " + f(a, 2) + " failed: boom");
  ASSERT_EQ(s->retry(a, {2}).status, RetryResult::retried);
  EXPECT_EQ(status(a).state, JobState::running);
  EXPECT_EQ(status(b).state, JobState::waiting);
  EXPECT_EQ(status(c).state, JobState::waiting);
  finish(f(a, 2));
  finish(f(b, 2));
  EXPECT_EQ(status(c).state, JobState::queued);
  finish(c);
}

TEST_F(DependencyTest, PerFrameNeedsSequencesWithTheFrames) {
  const std::string one = job(), a = sequence({1, 2});
  EXPECT_THROW(sequence({1}, {one}, true), std::invalid_argument);
  try {
    sequence({1, 2, 3, 4}, {a}, true);
    FAIL() << "accepted frames the dependency lacks";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "per-frame dependency " + a +
                                         " has no frame 3, 4 (2 of this sequence's frames): frame k waits for frame k "
                                         "of each job it names");
  }
  EXPECT_THROW(s->add_job(params({a}, true)), std::invalid_argument);
}

TEST_F(DependencyTest, APurgeThatWouldStrandAHeldJobIsRefused) {
  const std::string a = job(), b = job({a});
  s->fail_job(a, "x");
  const PurgeResult r = s->purge(a);
  EXPECT_EQ(r.status, PurgeResult::holds);
  EXPECT_EQ(r.held, std::vector<std::string>{b});
  ASSERT_EQ(s->cancel(b).status, CancelResult::cancelled);
  EXPECT_EQ(s->purge(a).status, PurgeResult::purged);
  // A dependency purged no longer holds anything back: b retried runs.
  ASSERT_EQ(s->retry(b).status, RetryResult::retried);
  EXPECT_EQ(status(b).state, JobState::queued);
}

TEST_F(DependencyTest, DependenciesSurviveARestart) {
  const std::string a = job(), b = job({a}), c = job({b});
  const std::string sa = sequence({1, 2}), sb = sequence({1, 2}, {sa}, true);
  s->fail_job(a, "lost");
  reopen();
  EXPECT_EQ(status(b).state, JobState::blocked);
  EXPECT_EQ(status(b).reason, "dependency " + a + " failed: lost");
  EXPECT_EQ(status(c).state, JobState::blocked);
  EXPECT_EQ(status(a).dependents, std::vector<std::string>{b});
  EXPECT_TRUE(status(sb).params.pipeline.per_frame);
  EXPECT_EQ(status(sb).state, JobState::waiting);
  EXPECT_EQ(s->leasable_tiles(worker), 2);  // sa's frames only
  ASSERT_EQ(s->retry(a).status, RetryResult::retried);
  finish(a);
  reopen();
  EXPECT_EQ(status(b).state, JobState::queued);
  EXPECT_EQ(status(c).state, JobState::waiting);
  finish(b);
  EXPECT_EQ(status(c).state, JobState::queued);
}

}  // namespace
}  // namespace tessera::server
