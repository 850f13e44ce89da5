// The read-only views of the scheduler: job snapshots and listings, a job's tiles, the workers with their leases and
// blocklists, the counters, and the jobs a restart left unfinalized.
#pragma once

#include "protocol/tile.h"
#include "protocol/worker.h"
#include "server/farm_state.h"
#include "server/scheduler_types.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tessera::server {

/// Queries of a FarmState, changing nothing; Scheduler documents each one. Not thread-safe: the scheduler calls it
/// under its lock, with the time of the call as `now`.
class FarmQueries {
 public:
  /// Queries of `s`, which must outlive it.
  explicit FarmQueries(const FarmState& s) : s_(s) {}

  /// A job's snapshot, or nothing for an unknown id.
  std::optional<JobStatus> job(const std::string& id, int64_t now) const;
  /// A page of a sequence's frames, or nothing for an unknown id or a job that is not a sequence.
  std::optional<FramePage> frames(const std::string& id, std::optional<int64_t> after, size_t limit, int64_t now) const;
  /// The jobs a query asks for, newest first (frames of sequences are not listed).
  JobPage jobs(const JobQuery& query, int64_t now) const;
  /// The submission number of a job, or nothing for an unknown id.
  std::optional<uint64_t> job_seq(const std::string& id) const;
  /// Every tile of a job in index order, or nothing for an unknown job.
  std::optional<protocol::TileList> tiles(const std::string& job) const;
  /// Every registered worker with its state, lease and blocklists.
  std::vector<protocol::WorkerInfo> workers(int64_t now) const;
  /// One registered worker as workers() shows it, or nothing for an unknown id.
  std::optional<protocol::WorkerInfo> worker(const std::string& id, int64_t now) const;
  /// Current counters.
  SchedulerCounters counters() const;
  /// Ids of started, unended jobs with every tile done.
  std::vector<std::string> unfinalized_jobs() const;

 private:
  const FarmState& s_;
};

}  // namespace tessera::server
