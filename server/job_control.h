// The operators' side of the scheduler: submitting jobs and changing them (cancel, retry, pause, resume, priority,
// requeueing a tile, raising the spp, purging), ending them once their image is written, and draining workers.
#pragma once

#include "server/farm_state.h"
#include "server/scheduler_types.h"

#include <cstdint>
#include <string>

namespace tessera::server {

/// The job operations on a FarmState; Scheduler documents each one. Not thread-safe: the scheduler calls it under its
/// lock, with the time of the call as `now`.
class JobControl {
 public:
  /// Operations on `s`, which must outlive it.
  explicit JobControl(FarmState& s) : s_(s) {}

  /// Throws std::invalid_argument for sizes a job cannot have (checked before add_job).
  static void check_params(const JobParams& params);
  /// Adds a queued job under `id` (empty: a fresh one) and returns the id.
  std::string add_job(const JobParams& params, const std::string& id, int64_t now);
  /// Cancels a queued or running job.
  CancelResult cancel(const std::string& job, int64_t now);
  /// Puts a failed or cancelled job back in the queue.
  RetryResult retry(const std::string& job);
  /// Pauses (true) or resumes (false) a job.
  PauseResult set_paused(const std::string& job, bool paused);
  /// Renders a tile of a job again.
  RequeueResult requeue(const std::string& job, int64_t tile);
  /// Changes the priority of a job that has not ended.
  PriorityResult set_priority(const std::string& job, int priority);
  /// Raises a job's spp.
  RaiseResult raise_spp(const std::string& job, uint32_t spp, int64_t now);
  /// Forgets an ended job.
  PurgeResult purge(const std::string& job);
  /// Marks a job whose tiles are all merged done.
  void complete_job(const std::string& job, int64_t now);
  /// Marks an unfinished job failed with a reason.
  void fail_job(const std::string& job, const std::string& error, int64_t now);
  /// Drains or undrains a worker; false for an unknown id.
  bool set_drained(const std::string& worker, bool drained);

 private:
  // Runs f(job record, result) when `job` is known; for an unknown job the result is R as default-constructed (whose
  // status says so).
  template <class R, class F>
  R with_job(const std::string& job, F&& f) {
    R r;
    if (JobRec* j = s_.find_job(job)) f(*j, r);
    return r;
  }

  FarmState& s_;
};

}  // namespace tessera::server
