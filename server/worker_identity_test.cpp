// One identity per worker: each registration's secret, checked for the worker and for each of its leases; the bound
// on registered workers and the rate of registrations; offline workers forgotten after their retention.
#include "server/registration_limit.h"
#include "server/scheduler.h"
#include "server/worker_secret.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace tessera::server {
namespace {

TEST(WorkerSecret, FreshRandomAndCheckedAgainstItsHashOnly) {
  const std::string a = new_worker_secret(), b = new_worker_secret();
  EXPECT_EQ(a.size(), 48u) << "192 bits as hex";
  EXPECT_NE(a, b);
  const std::string hash = worker_secret_hash(a);
  EXPECT_EQ(hash.size(), 64u);
  EXPECT_EQ(hash.find(a), std::string::npos);
  EXPECT_TRUE(worker_secret_matches(hash, a));
  EXPECT_FALSE(worker_secret_matches(hash, b));
  EXPECT_FALSE(worker_secret_matches(hash, ""));
  EXPECT_FALSE(worker_secret_matches(hash, a + "x"));
  EXPECT_FALSE(worker_secret_matches("", "")) << "a worker stored without a secret matches none";
}

TEST(RegistrationLimit, AMinutesWorthAtOnceThenTheRate) {
  RegistrationLimit limit(2);  // 2 a minute: one every 30 s, two at once
  EXPECT_EQ(limit.take(0), 0);
  EXPECT_EQ(limit.take(0), 0);
  EXPECT_EQ(limit.take(0), 30'000) << "the third waits for the bucket to refill";
  EXPECT_EQ(limit.take(29'999), 1);
  EXPECT_EQ(limit.take(30'000), 0);
  EXPECT_GT(limit.take(30'000), 0);
  EXPECT_EQ(limit.take(10'000), 30'000) << "a clock that steps back gives nothing";
  EXPECT_EQ(limit.take(10'000'000), 0);
  EXPECT_EQ(limit.take(10'000'000), 0) << "a long pause refills up to a minute's worth";
  EXPECT_GT(limit.take(10'000'000), 0);

  RegistrationLimit slow(0.5);  // below one a minute: one at a time
  EXPECT_EQ(slow.take(0), 0);
  EXPECT_EQ(slow.take(0), 120'000);

  RegistrationLimit none(0);
  for (int i = 0; i < 1000; ++i) ASSERT_EQ(none.take(0), 0);
}

// A scheduler on a manual clock: 1 s leases, workers gone after 2 s and forgotten 10 s after they were last seen.
struct WorkerIdentityTest : ::testing::Test {
  static SchedulerConfig config() {
    SchedulerConfig c;
    c.lease_ms = 1'000;
    c.worker_gone_ms = 2'000;
    c.worker_retention_ms = 10'000;
    c.max_workers = 3;
    return c;
  }
  int64_t now = 1'000'000;
  Scheduler s{config(), [this] { return now; }};

  std::string job() {
    JobParams p;
    p.width = 128;
    p.height = 128;
    p.tile_size = 64;
    p.spp = 1;
    p.scene_hash = "abc";
    return s.add_job(p);
  }
  std::vector<std::string> listed() {
    std::vector<std::string> ids;
    for (const protocol::WorkerInfo& w : s.workers()) ids.push_back(w.id);
    return ids;
  }
};

TEST_F(WorkerIdentityTest, EachWorkerAndEachOfItsLeasesAnswersToItsOwnSecretOnly) {
  const RegisterResult a = s.register_worker("a"), b = s.register_worker("b");
  ASSERT_EQ(a.status, RegisterResult::registered);
  ASSERT_EQ(b.status, RegisterResult::registered);
  EXPECT_NE(a.secret, b.secret);
  EXPECT_EQ(s.check_worker(a.id, a.secret), WorkerCheck::ok);
  EXPECT_EQ(s.check_worker(a.id, b.secret), WorkerCheck::wrong_secret);
  EXPECT_EQ(s.check_worker(a.id, ""), WorkerCheck::wrong_secret);
  EXPECT_EQ(s.check_worker("w-nobody", a.secret), WorkerCheck::unknown_worker);

  job();
  const AcquireResult l = s.acquire(a.id);
  ASSERT_EQ(l.status, AcquireResult::granted);
  std::string holder;
  EXPECT_EQ(s.check_lease_holder(l.lease.id, a.secret, &holder), WorkerCheck::ok);
  EXPECT_EQ(holder, a.id);
  EXPECT_EQ(s.check_lease_holder(l.lease.id, b.secret, &holder), WorkerCheck::wrong_secret) << "b's secret, a's lease";
  EXPECT_EQ(s.check_lease_holder(l.lease.id, "", &holder), WorkerCheck::wrong_secret);
  EXPECT_EQ(s.check_lease_holder("l-nope", a.secret, &holder), WorkerCheck::unknown_lease);
}

TEST_F(WorkerIdentityTest, RegistrationsStopAtTheBoundUntilAWorkerIsForgotten) {
  const std::string first = s.register_worker("1").id;
  now += 5'000;
  s.register_worker("2");
  s.register_worker("3");
  const RegisterResult full = s.register_worker("4");
  EXPECT_EQ(full.status, RegisterResult::full);
  EXPECT_TRUE(full.id.empty());
  EXPECT_TRUE(full.secret.empty());
  EXPECT_EQ(s.workers().size(), 3u);
  now += 5'001;  // the first was last seen 10.001 s ago: forgotten, its place free
  const RegisterResult again = s.register_worker("4");
  EXPECT_EQ(again.status, RegisterResult::registered);
  EXPECT_FALSE(s.has_worker(first));
  EXPECT_EQ(s.workers().size(), 3u);
}

TEST_F(WorkerIdentityTest, OfflineWorkersAreForgottenAfterTheirRetentionButNotWhileTheyHoldALease) {
  const RegisterResult idle = s.register_worker("idle"), busy = s.register_worker("busy"),
                       seen = s.register_worker("seen");
  const std::string j = job();
  const AcquireResult l = s.acquire(busy.id);
  ASSERT_EQ(l.status, AcquireResult::granted);
  for (int i = 1; i <= 28; ++i) {  // 14 s in which busy heartbeats its lease every 0.5 s
    now += 500;
    if (i == 18) {  // 9 s on; never heartbeaten
      ASSERT_EQ(s.acquire(seen.id).status, AcquireResult::granted);
    }
    ASSERT_EQ(s.heartbeat(l.lease.id).status, HeartbeatResult::ok);
  }
  // idle (last seen 14 s ago) is forgotten; busy (heartbeating) and seen (last seen 5 s ago) are not.
  EXPECT_EQ(listed(), (std::vector<std::string>{busy.id, seen.id}));
  EXPECT_EQ(s.check_worker(idle.id, idle.secret), WorkerCheck::unknown_worker);
  EXPECT_EQ(s.acquire(idle.id).status, AcquireResult::unknown_worker) << "a forgotten worker registers again";

  // busy stops: its lease expires a lease length after its last heartbeat, and it is forgotten once its retention
  // has passed; a request on its old lease is then one from an unknown worker.
  now += 1'001;
  EXPECT_EQ(s.job(j)->tiles.pending, 4) << "both leases expired";
  now += 10'000;
  EXPECT_EQ(listed(), std::vector<std::string>{});
  std::string holder;
  EXPECT_EQ(s.check_lease_holder(l.lease.id, busy.secret, &holder), WorkerCheck::unknown_worker);
  EXPECT_EQ(holder, busy.id);
  EXPECT_EQ(s.job(j)->tiles.pending, 4) << "forgetting lost nothing";

  const RegisterResult back = s.register_worker("busy");
  ASSERT_EQ(back.status, RegisterResult::registered);
  EXPECT_NE(back.id, busy.id) << "ids are never handed out twice";
  EXPECT_EQ(s.acquire(back.id).status, AcquireResult::granted);
}

TEST_F(WorkerIdentityTest, ALeaseHoldsItsWorkerEvenWhenRetentionIsShorterThanTheLease) {
  SchedulerConfig c = config();
  c.lease_ms = 60'000;
  c.worker_gone_ms = 1'000;
  c.worker_retention_ms = 1'000;
  Scheduler t{c, [this] { return now; }};
  JobParams p;
  p.width = p.height = p.tile_size = 64;
  p.spp = 1;
  t.add_job(p);
  const RegisterResult holder = t.register_worker("holder"), other = t.register_worker("other");
  ASSERT_EQ(t.acquire(holder.id).status, AcquireResult::granted);
  now += 30'000;
  EXPECT_EQ(t.workers().size(), 1u) << "other is forgotten, holder (leased) is not";
  EXPECT_FALSE(t.has_worker(other.id));
  EXPECT_TRUE(t.has_worker(holder.id));
  now += 30'001;  // the lease has run out
  t.expire();
  EXPECT_FALSE(t.has_worker(holder.id));
  EXPECT_EQ(t.jobs().front().tiles.pending, 1);
}

}  // namespace
}  // namespace tessera::server
