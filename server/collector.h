// Deleting what the farm no longer needs: purged jobs (on request, and finished jobs past their retention time) and
// blobs that no remaining job references.
#pragma once

#include "server/job_service.h"
#include "server/scheduler.h"
#include "server/storage.h"

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace tessera::server {

/// How long finished jobs and unreferenced blobs are kept.
struct RetentionOptions {
  std::optional<int64_t> retain_finished_ms;  ///< Jobs that ended longer ago are purged by sweep(); none: kept forever.
  int64_t blob_grace_ms = 3'600'000;          ///< A blob stored or touched more recently is kept even if unreferenced.
};

/// What one sweep deleted.
struct SweepReport {
  std::vector<std::string> purged_jobs;  ///< Finished jobs past their retention time.
  size_t blobs_removed = 0;              ///< Unreferenced blobs past their grace period.
};

/// Purges jobs and collects blobs. Thread-safe (one collection at a time).
class Collector {
 public:
  /// A collector over the coordinator's state (all references must outlive it), reading time from `clock`.
  Collector(JobService& jobs, Scheduler& scheduler, BlobStore& blobs, ClockMs clock, RetentionOptions options);

  /// Purges a finished job (see JobService::purge) and then collects blobs. Returns the state it had.
  protocol::JobState purge(const std::string& job);
  /// Purges every finished job that ended more than retain_finished_ms ago, then collects blobs.
  SweepReport sweep();
  /// Deletes the blobs no remaining job references that were not stored or touched within the grace period, while
  /// submissions are held back (a submission that checked its blobs before stores its job after). Returns how many.
  size_t collect_blobs();
  /// The options it runs with.
  const RetentionOptions& options() const { return opt_; }

 private:
  JobService& jobs_;
  Scheduler& sched_;
  BlobStore& blobs_;
  ClockMs clock_;
  RetentionOptions opt_;
  std::mutex mu_;  // one collection at a time
};

}  // namespace tessera::server
