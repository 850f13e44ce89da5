// The workers' side of the scheduler: registering, asking for work, heartbeats, result uploads (check, claim, finish,
// abandon), failure reports, releases, and the expiry and timeout of leases.
#pragma once

#include "server/farm_state.h"
#include "server/scheduler_types.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tessera::server {

/// The lease operations on a FarmState; Scheduler documents each one. Not thread-safe: the scheduler calls it under
/// its lock, with the time of the call as `now`.
class LeaseFlow {
 public:
  /// Operations on `s`, which must outlive it.
  explicit LeaseFlow(FarmState& s) : s_(s) {}

  /// Registers a worker offering `tags` whose secret hashes to `secret_hash` and returns its id; "" when max_workers
  /// are registered.
  std::string register_worker(const std::string& name, int64_t threads, const std::vector<std::string>& tags,
                              const std::string& secret_hash, int64_t now);
  /// Whether `secret` is the secret of the worker `worker`.
  WorkerCheck check_worker(const std::string& worker, std::string_view secret) const;
  /// Whether `secret` is the secret of the worker the lease was granted to; sets `holder` to that worker's id.
  WorkerCheck check_lease_holder(const std::string& lease, std::string_view secret, std::string* holder) const;
  /// Leases the next tile the worker may take.
  AcquireResult acquire(const std::string& worker, int64_t now);
  /// How many tiles acquire() could lease to the worker now.
  int64_t leasable_tiles(const std::string& worker) const;
  /// Extends a live lease and counts its rays.
  HeartbeatResult heartbeat(const std::string& lease, uint64_t rays, int64_t now);
  /// What an upload for this lease would do, changing nothing.
  ResultClaim check_result(const std::string& lease);
  /// Claims the lease's tile for merging.
  ResultClaim claim_result(const std::string& lease, int64_t now);
  /// Marks a claimed tile done and writes the change to the store at once (restoring the tile when that throws); sets
  /// `tile_key` to (job, tile) for flushed().
  /// Keeps `log` (the lines sent with the upload) as the tile's done log, within the job's bound.
  FinishResult finish_result(const std::string& lease, uint64_t rays, std::string_view pixels,
                             std::vector<std::string> log, int64_t now, std::pair<std::string, int64_t>* tile_key);
  /// The tile's done state, committed earlier, is now on the disk: it counts as done in snapshots from now on.
  void flushed(const std::string& job, int64_t tile);
  /// Gives up a claimed tile's merge.
  void abandon_result(const std::string& lease, int64_t now);
  /// Records that the lease's worker could not render its tile.
  FailResult fail(const std::string& lease, const std::string& error, const std::vector<std::string>& log, int64_t now);
  /// Hands a live lease's tile back without counting a failure; false for an unknown lease.
  bool release(const std::string& lease);
  /// Reclaims leases past their deadline and fails those past their job's tile timeout.
  void expire(int64_t now);
  /// Forgets the workers that are not present, hold no live lease and were last seen more than the retention time
  /// ago (SchedulerConfig::worker_retention_ms).
  void forget_workers(int64_t now);

 private:
  // The job whose tile the worker gets next (docs/protocol.md, "Sharing the farm"): each owner's first job in queue
  // order that the worker may take (its tags, the job's and the owner's caps, its blocklist), then the owner furthest
  // below its weighted share of the leases; nullptr when none. Jobs the worker is blocklisted for go to `stuck`.
  JobRec* pick_job(const std::string& worker, const WorkerRec& w, std::vector<JobRec*>& stuck) const;
  // The result claim's view of the lease, with its job and lease records (unset for an unknown lease).
  ResultClaim claim_view(const std::string& lease, JobRec** job_out, LeaseRec** lease_out);
  // When lease l next needs a look: the first moment it has expired or timed out.
  int64_t expiry_check_ms(const LeaseRec& l) const;
  // A lease became live: expire() looks at it by its expiry_check_ms.
  void watch(const LeaseRec& l) { next_expiry_check_ms_ = std::min(next_expiry_check_ms_, expiry_check_ms(l)); }

  FarmState& s_;
  // No live lease can expire or time out before this (a lower bound: heartbeats only move deadlines later), so
  // expire() skips its scan of the live leases until then.
  int64_t next_expiry_check_ms_ = 0;
  // No worker can be due to be forgotten before this (last-seen times only grow), so forget_workers() skips its scan
  // of the workers until then.
  int64_t next_forget_check_ms_ = 0;
};

}  // namespace tessera::server
