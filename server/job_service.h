// The coordinator's jobs behind the HTTP layer: admission (limits, scene validation), the stored spec of each job,
// running jobs' images, accepting tiles, finalisation and recovery after a restart. Knows nothing of HTTP; refusals
// are protocol::ApiError (with the status to answer) or protocol::ProtocolError (400).
#pragma once

#include "protocol/messages.h"
#include "protocol/tile.h"
#include "server/assembly.h"
#include "server/metrics.h"
#include "server/scheduler.h"
#include "server/storage.h"

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace tessera::server {

/// What one job may ask for, and how many may wait.
struct AdmissionLimits {
  int64_t max_queued_jobs = 1000;                ///< Queued plus running jobs; more submissions get 429.
  int retry_after_seconds = 30;                  ///< Retry-After announced with 429.
  uint64_t max_job_pixels = uint64_t(1) << 26;   ///< width x height of one job (the merged image lives in memory).
  double max_job_samples = 4e10;                 ///< width x height x spp (x max_spp when adaptive) of one job.
};

/// How an upload was settled.
enum class UploadOutcome { accepted, duplicate, discarded };

/// The name the protocol gives an outcome ("accepted", "duplicate", "discarded").
const char* to_string(UploadOutcome o);

/// Jobs from submission to result. Thread-safe.
class JobService {
 public:
  /// A service over the given state; all references must outlive it.
  JobService(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock,
             AdmissionLimits limits);

  /// Checks the submission (asset paths, uploaded assets, the scene as `tessera render` loads it, size limits),
  /// stores its spec and queues it. Throws ApiError: 400 for bad input, 429 when the queue is full.
  protocol::SubmitAnswer submit(const protocol::JobSubmission& submission);
  /// A job's snapshot; ApiError 404 for unknown ids.
  protocol::JobStatus status(const std::string& id);
  /// Every job, newest first.
  std::vector<protocol::JobStatus> list();
  /// Cancels a queued or running job; ApiError 404 unknown, 409 already ended.
  protocol::JobStatus cancel(const std::string& id);
  /// Puts a failed or cancelled job back in the queue; only its tiles that are not done are rendered again. ApiError
  /// 404 unknown, 409 for queued, running and done jobs.
  protocol::JobStatus retry(const std::string& id);
  /// Pauses a queued or running job (no new leases; running tiles finish). ApiError 404 unknown, 409 other states.
  protocol::JobStatus pause(const std::string& id);
  /// Resumes a paused job. ApiError 404 unknown, 409 a job that is not paused.
  protocol::JobStatus resume(const std::string& id);
  /// Changes a job's priority; ApiError 404 unknown, 409 ended.
  protocol::JobStatus set_priority(const std::string& id, int priority);
  /// What workers need to build the job; ApiError 404.
  protocol::JobSpec spec(const std::string& id);
  /// The merged EXR of a done job; ApiError 404 unknown, 409 not done.
  std::string result_exr(const std::string& id);
  /// The image as far as it has rendered, as PNG; ApiError 404.
  std::vector<uint8_t> preview_png(const std::string& id);

  /// Validates and merges an uploaded tile (rays add to the job's count); ApiError 404 unknown lease, 422 invalid
  /// (counted as the worker's failure). The upload that completes the job writes its result.
  UploadOutcome accept_tile(const std::string& lease, const std::string& exr, uint64_t rays);
  /// Records a worker's failure report with the log lines it sent; ApiError 404 for unknown leases.
  void record_failure(const std::string& lease, const protocol::FailReport& report);
  /// Every tile of a job (state, worker, attempts, render time, rays, failures with log lines); ApiError 404.
  protocol::TileList tiles(const std::string& id);
  /// Renders tile `tile` (its number as in the URL) of a running, paused or failed job again; the tile as it is now.
  /// ApiError 404 unknown job or tile, 409 for other job states, a pending tile without failures or one being merged.
  protocol::TileInfo requeue_tile(const std::string& id, const std::string& tile);

  /// After a restart: finishes jobs whose every tile was stored but whose result was not written yet.
  void recover();
  /// The limits it admits jobs under.
  const AdmissionLimits& limits() const { return limits_; }

 private:
  int64_t unfinished_jobs();
  void check_assets(const protocol::JobSubmission& submission);
  std::shared_ptr<JobImage> image_for(const std::string& job, int width, int height);
  void drop_image(const std::string& job);
  void finalize(const std::string& job);
  void after_failure(const std::string& job, const FailResult& f);

  Scheduler& sched_;
  BlobStore& blobs_;
  JobStore& jobs_;
  Metrics& metrics_;
  ClockMs clock_;
  AdmissionLimits limits_;
  std::mutex mu_;
  std::mutex admit_mu_;                                      // makes the queued-jobs check and add_job one step
  std::map<std::string, std::shared_ptr<JobImage>> images_;  // running jobs' images (a cache of the stored tiles)
  std::map<std::string, protocol::JobSpec> specs_;           // a cache of the stored specs
};

}  // namespace tessera::server
