// The coordinator's jobs behind the HTTP layer: admission (limits, scene validation), the stored spec of each job,
// running jobs' images, accepting tiles, finalisation and recovery after a restart. Knows nothing of HTTP; refusals
// are protocol::ApiError (with the status to answer) or protocol::ProtocolError (400).
#pragma once

#include "core/scene/checked_files.h"
#include "core/scene/obj_mesh.h"
#include "core/util/enum_names.h"
#include "protocol/messages.h"
#include "protocol/query.h"
#include "protocol/tile.h"
#include "server/assembly.h"
#include "server/disk_space.h"
#include "server/farm_events.h"
#include "server/metrics.h"
#include "server/preview_cache.h"
#include "server/scheduler.h"
#include "server/steps/step_runner.h"
#include "server/storage.h"
#include "server/webhook_url.h"

#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// What one job may ask for, and how many may wait.
struct AdmissionLimits {
  int64_t max_queued_jobs = 1000;                ///< Queued plus running jobs; more submissions get 429.
  int retry_after_seconds = 30;                  ///< Retry-After announced with 429.
  uint64_t max_job_pixels = uint64_t(1) << 26;   ///< width x height of one job (the merged image lives in memory).
  double max_job_samples = 4e10;                 ///< width x height x spp (x max_spp when adaptive) of one job.
  AssetLimits assets;  ///< Each image texture's and mesh's size, checked from its header (or count) at submission.
  int64_t max_job_frames = protocol::kDefaultMaxJobFrames;  ///< Frames of one sequence.
  WebhookAllowList notify_allowed;  ///< The webhook addresses a submission's "notify" may name (none: no address).
};

/// How an upload was settled (its name is the result answer's "status").
using UploadOutcome = protocol::UploadStatus;

/// Where an upload's answer goes once it may be given: its outcome, or (error set) the refusal to answer with
/// (protocol::ApiError, or another exception for a 500).
using UploadDone = std::function<void(UploadOutcome outcome, std::exception_ptr error)>;

/// Runs work that may take long (writing a finished job's result, asking for the next lease) somewhere it blocks
/// nobody; by default, at once.
using Background = std::function<void(std::function<void()>)>;

/// `background`, or one that runs the work at once when it is empty (the default of the classes that take one).
inline Background at_once_if_empty(Background background) {
  if (!background) background = [](std::function<void()> work) { work(); };
  return background;
}

/// Jobs from submission to result. Thread-safe. Every change of a job, and every tile done or failed, is published
/// to `events` after it happened.
class JobService {
 public:
  /// A service over the given state, noting in `disk` when a result finds the disk full, writing finished jobs'
  /// results through `results` (the upload that finished a job is answered once its result is written); all
  /// references must outlive it.
  JobService(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock,
             AdmissionLimits limits, FarmEvents& events, DiskSpace& disk, Background results = {});

  /// Checks the submission (asset paths, uploaded assets, the scene as `tessera render` loads it, size limits; every
  /// frame of a sequence, whose sentence then names the frame), stores its spec (each frame's) and queues it, all or
  /// nothing, as the job of user `owner`. Throws ApiError: 400 for bad input, 429 when the queue is full.
  protocol::SubmitAnswer submit(const protocol::JobSubmission& submission, const std::string& owner = "");
  /// A page of a sequence's frames (docs/protocol.md, "Sequences"); ApiError 404 unknown, 409 not a sequence.
  protocol::FrameList frames(const std::string& id, const protocol::FrameListQuery& query);
  /// The job of frame `frame` (its number as in the URL) of a sequence; ApiError 404 unknown job or frame, 409 not a
  /// sequence.
  std::string frame_job(const std::string& id, const std::string& frame);
  /// A job's snapshot; ApiError 404 for unknown ids.
  protocol::JobStatus status(const std::string& id);
  /// Runs the steps of jobs it finishes on `runner` and lists their outputs in status() (set before the service is
  /// shared; nullptr: no steps).
  void use_steps(StepRunner* runner) { steps_ = runner; }
  /// Every job, newest first.
  std::vector<protocol::JobStatus> list();
  /// The jobs a listing asks for, newest first, with the cursor of the next page ("c<seq>"; `after` also takes a job
  /// id). ApiError 400 for an `after` that is neither.
  protocol::JobList list(const protocol::JobListQuery& query);
  /// Cancels a queued or running job; ApiError 404 unknown, 409 already ended.
  protocol::JobStatus cancel(const std::string& id);
  /// Puts a failed or cancelled job back in the queue; only its tiles that are not done are rendered again. A
  /// sequence retries its failed and cancelled frames (those numbered in `frames`, when given). ApiError 404 unknown
  /// job or frame, 409 for queued, running and done jobs (a sequence: when no chosen frame failed or was cancelled),
  /// 400 frames given for a job that is not a sequence.
  protocol::JobStatus retry(const std::string& id, const std::vector<int64_t>& frames = {});
  /// Pauses a queued or running job (no new leases; running tiles finish). ApiError 404 unknown, 409 other states.
  protocol::JobStatus pause(const std::string& id);
  /// Resumes a paused job. ApiError 404 unknown, 409 a job that is not paused.
  protocol::JobStatus resume(const std::string& id);
  /// Changes a job's priority; ApiError 404 unknown, 409 ended.
  protocol::JobStatus set_priority(const std::string& id, int priority);
  /// Raises a resumable job's spp (server/job_refine.h, which defines this and the next two) and returns it as raised (every tile pending): ApiError 404
  /// unknown, 409 with the reason it cannot be exact, 400 over the sample limit.
  protocol::JobStatus raise_spp(const std::string& id, uint32_t spp);
  /// What workers need to build the job; ApiError 404.
  protocol::JobSpec spec(const std::string& id);
  /// The spec as its JSON answer, made once per job (not per request); ApiError 404.
  std::string spec_json(const std::string& id);
  /// A granted lease as answered: for a resumable job, marked so and naming the spp of the tile's stored state.
  protocol::Lease with_state(protocol::Lease lease);
  /// The stored state (EXR bytes) of a lease's tile, to continue from; ApiError 404 when there is none.
  std::string lease_state(const std::string& lease);
  /// Where the merged EXR of a done job is stored; ApiError 404 unknown, 409 not done.
  std::filesystem::path result_exr(const std::string& id);
  /// The image as far as it has rendered, as PNG (server/preview.h), made again only once the job's pixels have
  /// changed (server/preview_cache.h); ApiError 404.
  std::vector<uint8_t> preview_png(const std::string& id, std::optional<Layer> layer = std::nullopt);

  /// Allocates the image a started job's tiles are pasted into, where results are written (in the background), so
  /// that its first tile's upload does not wait for the image's megabytes to be zeroed; called at its first lease.
  void prepare_image(const std::string& job);

  /// Validates and merges an uploaded tile (rays add to the job's count) and calls `done` once: `accepted` only after
  /// the tile's pixels are on the disk (a group commit: concurrent uploads share one flush, and no thread waits for
  /// it), `duplicate` once what it duplicates is, `discarded` at once; refusals ApiError 404 unknown lease, 422
  /// invalid (counted as the worker's failure). The upload that completes the job writes its result (in the
  /// background) before it is answered. `exr` is read only before this returns. `stored`, when given, runs on the
  /// calling thread once the tile is stored and before this returns (its flush may be done by then, and `done`
  /// called), for an upload that is neither refused, discarded nor a duplicate; it must not throw.
  void accept_tile(const std::string& lease, std::string_view exr, uint64_t rays, std::vector<std::string> log,
                   UploadDone done, const std::function<void()>& stored = {});
  /// As above, waiting for the answer; throws the refusal.
  UploadOutcome accept_tile(const std::string& lease, std::string_view exr, uint64_t rays,
                            std::vector<std::string> log = {});
  /// Records a worker's failure report with the log lines it sent; ApiError 404 for unknown leases.
  void record_failure(const std::string& lease, const protocol::FailReport& report);
  /// Every tile of a job (state, worker, attempts, render time, rays, failures with log lines); ApiError 404.
  protocol::TileList tiles(const std::string& id);
  /// Renders tile `tile` (its number as in the URL) of a running, paused or failed job again; the tile as it is now.
  /// ApiError 404 unknown job or tile, 409 for other job states, a pending tile without failures or one being merged.
  protocol::TileInfo requeue_tile(const std::string& id, const std::string& tile);

  /// Deletes a done, failed or cancelled job: its rows, tile pixels and spec (one store change), then its result file.
  /// ApiError 404 unknown, 409 not ended (or an upload of it is being stored). Returns its state before.
  protocol::JobState purge(const std::string& id);
  /// Every blob a remaining job's spec names.
  std::set<std::string> referenced_blobs();
  /// Holds submissions back while locked: a blob that no job references and that is not touched meanwhile stays
  /// unreferenced until it is released (a submission checks its blobs again under this lock before it is stored).
  std::unique_lock<std::mutex> hold_submissions() { return std::unique_lock(admit_mu_); }

  /// After a restart: finishes jobs whose every tile was stored but whose result was not written yet, and deletes
  /// result files of jobs purged before a crash let them go.
  void recover();
  /// Writes the results of jobs whose every tile is stored but whose result found the disk full (such a job stays
  /// running, its tiles kept, instead of failing); those that still do not fit wait for the next call, and it then
  /// returns false.
  bool write_waiting_results();
  /// The limits it admits jobs under.
  const AdmissionLimits& limits() const { return limits_; }

 private:
  // What checking one scene found: the image it makes, its spp and hash, and what the loader had to say.
  struct CheckedScene {
    int width = 0;
    int height = 0;
    uint32_t spp = 0;
    std::string hash;
    std::vector<std::string> warnings;
    std::map<std::string, std::string> layer_metadata;  // the Cryptomatte attributes of the sampling's layers
  };
  int64_t unfinished_jobs();
  protocol::ApiError queue_full() const;  // the 429 of a submission beyond --max-queued-jobs
  // Stored blobs' files by SHA-256, looked up once for all the frames of a sequence (absent: not stored).
  using BlobFiles = std::map<std::string, std::filesystem::path>;
  // Throws ApiError 400 (its sentence starting with `where`: "" or "frame N: ") for bad or missing assets; `known`,
  // when given, answers which blobs are stored instead of the blob store.
  void check_assets(const nlohmann::json& scene, const std::map<std::string, std::string>& assets,
                    const std::string& where, const BlobFiles* known = nullptr);
  // Checks a scene as `tessera render` loads it (not built) and the job's size limits for it (`known` as above;
  // `objs`, when given, keeps the meshes parsed for the next scene of the same submission).
  CheckedScene check_scene(const nlohmann::json& scene, const std::map<std::string, std::string>& assets,
                           const protocol::SamplingSettings& sampling, const std::string& where,
                           const BlobFiles* known = nullptr, ObjParseCache* objs = nullptr);
  protocol::SubmitAnswer submit_sequence(const protocol::JobSubmission& submission, const std::string& owner);
  // The assets the job's spec names: from the cached spec, else read from its record without caching it (a blob
  // collection reads every frame's). ApiError 404 when there is neither; what the store throws.
  std::map<std::string, std::string> spec_assets(const std::string& id);
  // ApiError 409 when `id` is a frame of a sequence: `what` (pause, cancel...) acts on the whole sequence.
  void refuse_frame(const std::string& id, const char* what);
  /// The sampling settings of a resumable job; nothing for other jobs.
  std::optional<protocol::SamplingSettings> resumable_sampling(const std::string& job);
  /// The job's output layers, from its cached spec (none for a job without a record).
  LayerSet job_layers(const std::string& job);
  /// ApiError 400 when width x height x per_pixel samples are over the limit.
  void check_samples(int width, int height, uint32_t per_pixel, bool adaptive) const;
  std::shared_ptr<JobImage> image_for(const std::string& job, int width, int height);
  void drop_image(const std::string& job);
  void finalize(const std::string& job);
  void after_failure(const ResultClaim& tile, const std::string& error, const FailResult& f);
  protocol::JobStatus announce(const std::string& job);  // the job's snapshot, published as a job event
  void announce_frames(const std::string& job);  // a sequence's frames' snapshots, each published as a job event

  Scheduler& sched_;
  BlobStore& blobs_;
  JobStore& jobs_;
  Metrics& metrics_;
  ClockMs clock_;
  AdmissionLimits limits_;
  StepRunner* steps_ = nullptr;  // runs done jobs' steps (use_steps)
  FarmEvents& events_;
  DiskSpace& disk_;
  Background results_;
  std::mutex mu_;
  std::mutex admit_mu_;                                      // makes the queued-jobs check and add_job one step
  std::mutex raise_mu_;                                      // one raise_spp at a time (checks, scheduler, record)
  std::map<std::string, std::shared_ptr<JobImage>> images_;  // running jobs' images (a cache of the stored tiles)
  std::map<std::string, protocol::JobSpec> specs_;           // a cache of the stored specs
  std::map<std::string, std::string> spec_json_;             // the same as JSON answers (set and erased with specs_)
  CheckedFiles mesh_digests_;   // mesh blobs' digests, read once
  CheckedFiles checked_blobs_;  // image blobs earlier submissions decoded clean: the next check skips the decode
  std::set<std::string> waiting_results_;  // jobs whose result found the disk full (mu_)
  PreviewCache previews_;       // each job's latest preview PNG, by the version of the pixels it shows
  void cache_spec_locked(const std::string& id, const protocol::JobSpec& spec, bool replace);
};

}  // namespace tessera::server
