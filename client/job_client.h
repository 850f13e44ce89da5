// The client side of jobs: upload a scene's assets, submit it, follow its progress, download the result; and the
// operator's controls over jobs and workers (pause, priority, retry, cancel, the worker list, drain).
#pragma once

#include "client/http_client.h"
#include "protocol/access.h"
#include "protocol/audit.h"
#include "protocol/messages.h"
#include "protocol/query.h"
#include "protocol/tile.h"
#include "protocol/worker.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera::client {

/// The coordinator refused a request with a definitive answer; the message carries its explanation.
struct SubmitError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

using protocol::JobStatus;
using protocol::ProtocolError;

/// One frame of a sequence to submit: its number and its scene file.
struct FrameScene {
  int64_t number = 0;            ///< Frame number.
  std::filesystem::path scene;   ///< Its scene file (course JSON format).
};

/// What to submit: one scene, or a sequence of frames.
struct SubmitOptions {
  std::filesystem::path scene;         ///< Scene file (course JSON format); unused for a sequence.
  std::vector<FrameScene> frames;      ///< A sequence's frames in number order; empty: one image (`scene`).
  protocol::FrameOrder frame_order = protocol::FrameOrder::in_order;  ///< A sequence's lease order.
  protocol::SamplingSettings sampling; ///< How to sample (spp 0: the scene's).
  int tile_size = protocol::kDefaultTileSize;  ///< Tile edge in pixels.
  int priority = protocol::kDefaultPriority;   ///< Higher runs first.
  int64_t tile_timeout_seconds = protocol::kDefaultTileTimeoutSeconds;  ///< A lease older than this is revoked.
  std::string name;                    ///< Job label (default: the scene's file name).
  std::optional<std::filesystem::path> asset_root;  ///< Assets may lie anywhere below this folder.
  bool resumable = false;              ///< Tiles keep their exact sums, so the spp can be raised later.
  std::vector<std::string> require;    ///< Tags a worker must have to take its tiles.
  int64_t max_workers = 0;             ///< Its tiles leased at once at most; 0: no cap.
  protocol::Pipeline pipeline;         ///< Jobs it waits for, steps after its merge, its webhook.
};

/// Counts of a submission's asset uploads.
struct SubmitResult {
  std::string job_id;      ///< The new job's id.
  int assets_total = 0;    ///< Assets the scene uses.
  int assets_uploaded = 0; ///< Assets that were missing and uploaded.
};

/// One asset a scene uses, on this machine: its path in the scene, its file and the SHA-256 of its bytes.
struct LocalAsset {
  std::string path;            ///< As the scene names it.
  std::filesystem::path file;  ///< Where it is.
  std::string sha256;          ///< Hash of its bytes (lowercase hex).
};

/// One frame of a sequence read for submission.
struct FrameFiles {
  int64_t number = 0;              ///< Frame number.
  nlohmann::json scene;            ///< The frame's scene file's JSON.
  std::vector<LocalAsset> assets;  ///< Every asset it uses.
};

/// A scene file read for submission: its JSON and its assets, hashed; or a sequence's frames.
struct SceneFiles {
  nlohmann::json scene;            ///< The scene file's JSON (one image).
  std::vector<LocalAsset> assets;  ///< Every asset it uses (one image).
  std::vector<FrameFiles> frames;  ///< A sequence's frames (scene and assets above are then empty).
};

/// Reads the options' scene (or every frame's) and hashes its assets, each file once however many frames use it;
/// throws SceneError (unreadable scene, asset outside the allowed folder; a frame's names the frame) or SubmitError
/// (unreadable asset).
SceneFiles read_scene_files(const SubmitOptions& options);

/// What submit_job POSTs for a scene already read (read_scene_files with the same options).
protocol::JobSubmission job_submission(const SubmitOptions& options, SceneFiles files);

/// Hashes the scene's assets, uploads the missing ones (HEAD, then PUT), and POSTs the job, again after Retry-After
/// while the coordinator answers 503 (its admission pool full). Throws SubmitError with the coordinator's message for
/// other refusals, TransportError when it is unreachable, SceneError for unreadable scenes.
SubmitResult submit_job(HttpClient& http, const SubmitOptions& options);
/// As above, for a scene already read (read_scene_files with the same options).
SubmitResult submit_job(HttpClient& http, const SubmitOptions& options, SceneFiles files);

/// GET /v1/jobs/{id}; throws SubmitError (404 or other errors) or TransportError.
JobStatus get_job(HttpClient& http, const std::string& id);
/// GET /v1/jobs/{id}/spec: what the job renders (scene, assets, sampling settings, size); throws as get_job.
protocol::JobSpec get_job_spec(HttpClient& http, const std::string& id);

/// Follows the job until it is done, failed or cancelled, calling progress on each change: on the coordinator's
/// event stream (GET /v1/events, on a second connection) while it is available, else (refused, e.g. 503, or broken)
/// by polling every poll interval, where transport errors are retried with backoff (the coordinator may be
/// restarting) up to `give_up` in a row. Returns early (with the last status) when stop() says true. Without
/// `tile_progress`, the stream carries only job events (progress is then called on state changes only).
JobStatus wait_for_job(HttpClient& http, const std::string& id, const std::function<void(const JobStatus&)>& progress,
                       const std::function<bool()>& stop, std::chrono::milliseconds poll = std::chrono::milliseconds(200),
                       std::chrono::seconds give_up = std::chrono::seconds(120), bool tile_progress = true);

/// GET /v1/jobs/{id}/frames?after=&limit=: one page of a sequence's frames (their jobs), lowest number first.
protocol::FrameList list_frames(HttpClient& http, const std::string& id, const protocol::FrameListQuery& query);

/// Downloads frame `frame` of a sequence (GET /v1/jobs/{id}/frames/{n}/result.exr) to path atomically, as
/// download_result does; returns the number of bytes.
uint64_t download_frame(HttpClient& http, const std::string& id, int64_t frame, const std::filesystem::path& path);

/// Downloads the finished job's result.exr to path atomically (temporary file, fsync, rename); throws SubmitError
/// or TransportError. Returns the number of bytes.
uint64_t download_result(HttpClient& http, const std::string& id, const std::filesystem::path& path);

/// Downloads output `name` of a done job's steps (GET /v1/jobs/{id}/outputs/{name}) to path atomically, as
/// download_result does; returns the number of bytes.
uint64_t download_output(HttpClient& http, const std::string& id, const std::string& name,
                         const std::filesystem::path& path);

/// GET /v1/jobs: every job, newest first; throws SubmitError or TransportError.
std::vector<JobStatus> list_jobs(HttpClient& http);
/// GET /v1/jobs?state=&limit=&after=: one page of the jobs a query asks for, with the next page's cursor.
protocol::JobList list_jobs(HttpClient& http, const protocol::JobListQuery& query);

/// POST /v1/jobs/{id}/retry: the job queued again (a sequence: its failed and cancelled frames, those in `frames` when
/// given); throws SubmitError (404, 409 with the coordinator's sentence).
JobStatus retry_job(HttpClient& http, const std::string& id, const std::vector<int64_t>& frames = {});

/// PATCH /v1/jobs/{id} {"priority": N}: the job with its new priority; throws SubmitError (404, 409 ended).
JobStatus set_job_priority(HttpClient& http, const std::string& id, int priority);

/// PATCH /v1/jobs/{id} {"spp": M}: the resumable job, running again towards M samples per pixel with its stored tiles
/// continued; throws SubmitError (404, 409 with the reason it cannot be raised exactly).
JobStatus raise_job_spp(HttpClient& http, const std::string& id, uint32_t spp);

/// GET /v1/workers: every registered worker; throws SubmitError or TransportError.
std::vector<protocol::WorkerInfo> list_workers(HttpClient& http);
/// GET /v1/me: the user and role the coordinator takes this client's credential for.
protocol::Me whoami(HttpClient& http);
/// GET /v1/audit: a page of the audit trail, newest first (admins only: 403 otherwise).
protocol::AuditList list_audit(HttpClient& http, const protocol::AuditQuery& query);

/// POST /v1/workers/{id}/drain (drain true) or /undrain: the worker as it is now; throws SubmitError (404 unknown).
protocol::WorkerInfo drain_worker(HttpClient& http, const std::string& id, bool drain);

/// POST /v1/jobs/{id}/pause: the job, now paused; throws SubmitError (404, 409 with the coordinator's sentence).
JobStatus pause_job(HttpClient& http, const std::string& id);

/// GET /v1/jobs/{id}/tiles: every tile's state, worker, attempts, render time, rays and failures; throws SubmitError.
protocol::TileList get_job_tiles(HttpClient& http, const std::string& id);

/// POST /v1/jobs/{id}/tiles/{n}/requeue: the tile, pending again; throws SubmitError (404, 409 with the sentence).
protocol::TileInfo requeue_tile(HttpClient& http, const std::string& id, int64_t tile);

/// POST /v1/jobs/{id}/resume: the job, queued or running again; throws SubmitError (404, 409 not paused).
JobStatus resume_job(HttpClient& http, const std::string& id);

/// DELETE /v1/jobs/{id}?purge=true: deletes a job that has ended (its rows, pixels and result). Throws SubmitError
/// (404 unknown, 409 not ended) or TransportError.
protocol::PurgeAnswer purge_job(HttpClient& http, const std::string& id);

/// DELETE /v1/jobs/{id}; true when cancelled, false when it had already ended (409). Throws for other answers.
bool cancel_job(HttpClient& http, const std::string& id);

}  // namespace tessera::client
