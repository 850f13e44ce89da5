// The operators' side of the scheduler: submitting jobs and changing them (cancel, retry, pause, resume, priority,
// requeueing a tile, raising the spp, purging), ending them once their image is written, and draining workers.
#pragma once

#include "server/farm_state.h"
#include "server/scheduler_types.h"

#include <cstdint>
#include <string>
#include <vector>

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
  /// Adds a queued sequence under `id` (empty: a fresh one) with one queued job per frame (frame_job_id), in frame
  /// order, all in one change; returns the id. Each frame's size and spp are its own (checked before, by the
  /// scheduler), the rest `params`'; the sequence's size and spp are its first frame's.
  std::string add_sequence(const JobParams& params, const std::vector<FrameParams>& frames, const std::string& id,
                           int64_t now);
  /// Cancels a queued or running job (a sequence: its frames that have not ended).
  CancelResult cancel(const std::string& job, int64_t now);
  /// Puts a failed or cancelled job back in the queue (a sequence: its failed or cancelled frames, those numbered in
  /// `frames` when it is not empty).
  RetryResult retry(const std::string& job, const std::vector<int64_t>& frames, int64_t now);
  /// Pauses (true) or resumes (false) a job (a sequence: every frame that can be).
  PauseResult set_paused(const std::string& job, bool paused);
  /// Renders a tile of a job again.
  RequeueResult requeue(const std::string& job, int64_t tile);
  /// Changes the priority of a job that has not ended.
  PriorityResult set_priority(const std::string& job, int priority);
  /// Raises a job's spp.
  RaiseResult raise_spp(const std::string& job, uint32_t spp, int64_t now);
  /// Forgets an ended job (a sequence: with its frames).
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

  // Puts one failed or cancelled job back in the queue (it has ended and is not done).
  void retry_ended(JobRec& j, RetryResult& r, int64_t now);
  // One job's pause or resume; false when its state does not allow it.
  bool pause_one(JobRec& j, bool paused);

  FarmState& s_;
};

}  // namespace tessera::server
