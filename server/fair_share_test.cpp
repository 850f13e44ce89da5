// The shared farm's scheduling rules (docs/protocol.md, "Sharing the farm"): each lease goes to the owner furthest
// below its weighted share of the leases, then by priority and age within that owner; job and user caps; worker tags
// against job requirements, and the reason a job no worker may take is waiting.
#include "server/scheduler.h"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

namespace tessera::server {
namespace {

struct FairShareTest : ::testing::Test {
  int64_t now = 1'000'000;
  Scheduler s{SchedulerConfig{10'000, 3, 2, ""}, [this] { return now; }};

  // A job of `owner` with `tiles` 8x8 tiles in one row.
  std::string job(const std::string& owner, int tiles, int priority = 0, std::vector<std::string> require = {},
                  int64_t max_workers = 0) {
    JobParams p;
    p.priority = priority;
    p.width = 8 * tiles;
    p.height = 8;
    p.tile_size = 8;
    p.spp = 1;
    p.scene_hash = "h";
    p.owner = owner;
    p.require = std::move(require);
    p.max_workers = max_workers;
    return s.add_job(p);
  }
  // The owner of the job each of `workers` is leased next (one lease each, held).
  std::vector<std::string> lease_owners(const std::vector<std::string>& workers) {
    std::vector<std::string> owners;
    for (const std::string& w : workers) {
      const AcquireResult r = s.acquire(w);
      owners.push_back(r.status == AcquireResult::granted ? *s.job_owner(r.lease.job) : "-");
    }
    return owners;
  }
  std::vector<std::string> workers(int n, const std::vector<std::string>& tags = {}) {
    std::vector<std::string> out;
    for (int i = 0; i < n; ++i) out.push_back(s.register_worker("w" + std::to_string(i), 1, tags).id);
    return out;
  }
};

TEST_F(FairShareTest, EqualWeightsSplitTheWorkersWhateverThePriorities) {
  job("ana", 100, /*priority=*/50);  // a big, urgent job submitted first
  job("ben", 100, 0);
  const std::vector<std::string> owners = lease_owners(workers(10));
  EXPECT_EQ(std::count(owners.begin(), owners.end(), "ana"), 5);
  EXPECT_EQ(std::count(owners.begin(), owners.end(), "ben"), 5);
}

TEST_F(FairShareTest, WeightsSetTheShares) {
  s.set_shares({{"ana", OwnerShare{3, 0}}, {"ben", OwnerShare{1, 0}}});
  job("ana", 100);
  job("ben", 100);
  const std::vector<std::string> owners = lease_owners(workers(8));
  EXPECT_EQ(std::count(owners.begin(), owners.end(), "ana"), 6);
  EXPECT_EQ(std::count(owners.begin(), owners.end(), "ben"), 2);
}

TEST_F(FairShareTest, AnOwnerWithoutPendingWorkLeavesItsShareToTheOthers) {
  job("ana", 2);
  job("ben", 100);
  const std::vector<std::string> owners = lease_owners(workers(6));
  EXPECT_EQ(std::count(owners.begin(), owners.end(), "ana"), 2);
  EXPECT_EQ(std::count(owners.begin(), owners.end(), "ben"), 4);
}

TEST_F(FairShareTest, WithinAnOwnerPriorityThenAgeDecide) {
  const std::string low = job("ana", 10, 0);
  const std::string high = job("ana", 10, 5);
  for (const std::string& w : workers(3)) EXPECT_EQ(s.acquire(w).lease.job, high);
  (void)low;
}

TEST_F(FairShareTest, ALateSmallJobIsLeasedAtTheNextRequest) {
  job("ana", 1000);
  const std::vector<std::string> ws = workers(4);
  lease_owners(ws);  // ana holds all four
  const std::string small = job("ben", 2);
  // A worker that finishes asks again: ben's share (2 of 4) is far above its 0 leases.
  const AcquireResult r = s.acquire(s.register_worker("late", 1).id);
  ASSERT_EQ(r.status, AcquireResult::granted);
  EXPECT_EQ(r.lease.job, small);
}

TEST_F(FairShareTest, JobAndUserCapsBoundTheLeasesHeldAtOnce) {
  const std::string capped = job("ana", 100, 10, {}, /*max_workers=*/2);
  job("ana", 100, 0);
  s.set_shares({{"ben", OwnerShare{1, 1}}});
  job("ben", 100);
  const std::vector<std::string> ws = workers(6);
  std::map<std::string, int> by_job;
  for (const std::string& w : ws) {
    const AcquireResult r = s.acquire(w);
    ASSERT_EQ(r.status, AcquireResult::granted);
    ++by_job[r.lease.job];
  }
  EXPECT_EQ(by_job[capped], 2);
  int ben = 0;
  for (const auto& [id, n] : by_job)
    if (*s.job_owner(id) == "ben") ben += n;
  EXPECT_EQ(ben, 1);
  EXPECT_EQ(s.job(capped)->params.max_workers, 2);
}

TEST_F(FairShareTest, AJobAtItsCapCountsNoLeasableTilesAndItsEndedLeaseNotesWork) {
  int noted = 0;
  s.on_work([&] { ++noted; });
  const std::string capped = job("ana", 10, 0, {}, /*max_workers=*/1);
  const std::vector<std::string> ws = workers(2);
  const Lease l = s.acquire(ws[0]).lease;
  EXPECT_EQ(s.leasable_tiles(ws[1]), 0);  // a held lease request is not woken for tiles it cannot take
  EXPECT_EQ(s.acquire(ws[1]).status, AcquireResult::no_work);
  noted = 0;
  ASSERT_EQ(s.claim_result(l.id).status, ResultClaim::proceed);
  s.finish_result(l.id, 1);
  EXPECT_GE(noted, 1);  // the slot freed: held requests hear of it
  EXPECT_EQ(s.leasable_tiles(ws[1]), 1);
  EXPECT_EQ(s.acquire(ws[1]).lease.job, capped);
}

TEST_F(FairShareTest, RequirementsNeedEveryTagAndSayWhatTheyWaitFor) {
  const std::string big = job("ana", 4, 0, {"bigmem", "site-a"});
  const std::string plain = job("ana", 4, 0);
  EXPECT_EQ(s.job(big)->waiting_for.value_or(""), "a worker with tags bigmem, site-a");
  const std::string laptop = s.register_worker("laptop", 1, {"site-a"}).id;
  EXPECT_EQ(s.acquire(laptop).lease.job, plain);
  EXPECT_EQ(s.leasable_tiles(laptop), 3);
  EXPECT_TRUE(s.job(big)->waiting_for.has_value());
  const std::string server = s.register_worker("server", 1, {"bigmem", "gpu", "site-a"}).id;
  EXPECT_FALSE(s.job(big)->waiting_for.has_value());
  EXPECT_EQ(s.acquire(server).lease.job, big);
  EXPECT_FALSE(s.job(plain)->waiting_for.has_value());
  // Once the only worker with the tags leaves (not seen for three leases), the job says so again.
  now += 31'000;
  EXPECT_EQ(s.job(big)->waiting_for.value_or(""), "a worker with tags bigmem, site-a");
}

TEST_F(FairShareTest, OwnersFilterTheListing) {
  job("ana", 1);
  job("ben", 1);
  JobQuery q;
  q.owner = "ben";
  const JobPage page = s.jobs(q);
  ASSERT_EQ(page.jobs.size(), 1u);
  EXPECT_EQ(page.jobs[0].params.owner, "ben");
}

}  // namespace
}  // namespace tessera::server
