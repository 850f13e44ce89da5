// The farm protocol's request and answer bodies (docs/protocol.md, docs/openapi.yaml) as structs with their JSON
// form. A render option is one field of SamplingSettings: its JSON key, its check and its effect on loading and
// rendering are all written here.
#pragma once

#include "core/image/pixel_window.h"
#include "core/render/render_options.h"
#include "core/scene/load_options.h"
#include "protocol/defaults.h"
#include "protocol/headers.h"
#include "protocol/job.h"
#include "protocol/json_fields.h"
#include "protocol/routes.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// How a job's pixels are sampled: everything besides the scene that changes a pixel's bits.
struct SamplingSettings {
  uint32_t spp = 0;            ///< Samples per pixel (0 in a submission: the scene's; always set in a job spec).
  uint64_t seed = 0;           ///< Sample seed.
  std::string integrator;      ///< "direct" or "intersection_test": render other integrator types with it; "" off.
  double target_error = 0.0;   ///< Adaptive sampling target (0: every pixel gets spp samples).
  uint32_t min_spp = kDefaultMinSpp;  ///< Adaptive sampling: first round.
  uint32_t max_spp = kDefaultMaxSpp;  ///< Adaptive sampling: most samples per pixel.
  double error_floor = AdaptiveOptions{}.error_floor;  ///< Adaptive sampling: luminance floor of the relative error.
  uint32_t replicates = 1;     ///< Independent replicates per pixel (see core/sampling/adaptive.h).
  std::string area_sampling;   ///< Overrides the scene's integrator.area_sampling ("": the scene's).
  std::string env_sampling;    ///< Overrides the scene's integrator.env_sampling ("": the scene's).
  std::string bvh;             ///< Overrides the scene's integrator.bvh ("": the scene's).
  LayerSet layers;             ///< Output layers beside the colour (core/render/layers.h); JSON: an array of names.

  /// What loading the scene needs from these settings (spp override, integrator, strategy overrides).
  LoadOptions load_options() const;
  /// Sets the render options these settings decide (seed, adaptive sampling, replicates, layers).
  void apply_to(RenderOptions& options) const;
  /// The EXR metadata that records these settings (`tessera:spp`, `tessera:seed`, adaptive options, replicates,
  /// strategy overrides and `tessera:layers` when there are layers), written alike by `tessera render` and the coordinator, and read back by `render --resume`.
  std::map<std::string, std::string> metadata() const;
};

/// The settings as the keys a submission and a spec carry them with (those at their defaults left out).
void to_json(nlohmann::json& j, const SamplingSettings& s);

/// One frame of a sequence's submission: a full scene file of its own.
struct FrameSubmission {
  int64_t number = 0;                               ///< The frame's number (0 to kMaxFrameNumber, unique).
  nlohmann::json scene = nlohmann::json::object();  ///< The frame's scene file's JSON.
  /// Its own asset paths -> SHA-256, for paths that mean another file than in the submission's "assets" (those it does
  /// not name are the submission's).
  std::map<std::string, std::string> assets;
};

/// Body of POST /v1/jobs: one image (`scene`) or a sequence (`frames`, one scene each, sharing everything else).
struct JobSubmission {
  nlohmann::json scene = nlohmann::json::object();  ///< The scene file's JSON (empty for a sequence).
  std::map<std::string, std::string> assets;        ///< Asset path as written in the scene -> SHA-256.
  std::vector<FrameSubmission> frames;              ///< A sequence's frames in number order; empty: one image.
  FrameOrder frame_order = FrameOrder::in_order;    ///< The order a sequence's frames are leased in.
  SamplingSettings sampling;                        ///< How to sample.
  int tile_size = kDefaultTileSize;                 ///< Tile edge in pixels.
  int priority = kDefaultPriority;                  ///< Higher runs first.
  std::string name;                                 ///< Label.
  /// Keep each pixel's exact sums with its tile, so the job's spp can be raised later (docs/resume.md).
  bool resumable = false;
  int64_t tile_timeout_seconds = kDefaultTileTimeoutSeconds;  ///< A lease older than this is revoked (a failure).
  std::vector<std::string> require;  ///< Tags a worker must have to take its tiles (protocol/tags.h).
  int64_t max_workers = 0;           ///< Its tiles leased at once at most; 0: no cap.
  Pipeline pipeline;  ///< The jobs it waits for, the steps after its merge, its webhook (protocol/pipeline.h).
};
/// The submission's JSON (sampling settings at their defaults are left out).
void to_json(nlohmann::json& j, const JobSubmission& s);
/// Parses and checks a submission body; throws ProtocolError with the sentence the coordinator answers (400).
JobSubmission parse_job_submission(const std::string& body);

/// Body of PATCH /v1/jobs/{id}: a new priority (a job that has not ended) and/or a higher spp (a resumable job).
struct JobPatch {
  std::optional<int> priority;  ///< The new priority (higher runs first).
  std::optional<uint32_t> spp;  ///< The new samples per pixel (see server/job_refine.h).
};
void to_json(nlohmann::json& j, const JobPatch& p);
/// Parses a patch body ({"priority": N} and/or {"spp": M}, nothing else, at least one); throws ProtocolError with the
/// sentence answered (400).
JobPatch parse_job_patch(const std::string& body);

/// Answer 201 to POST /v1/jobs.
struct SubmitAnswer {
  std::string id;                     ///< The new job's id.
  std::vector<std::string> warnings;  ///< What the scene loader had to say.
};
void to_json(nlohmann::json& j, const SubmitAnswer& a);
void from_json(const nlohmann::json& j, SubmitAnswer& a);

/// What workers need to build and render a job: answer to GET /v1/jobs/{id}/spec, and the job's stored record.
struct JobSpec {
  nlohmann::json scene = nlohmann::json::object();  ///< The scene file's JSON.
  std::map<std::string, std::string> assets;        ///< Asset path as written in the scene -> SHA-256.
  SamplingSettings sampling;                        ///< How to sample (spp set).
  int width = 0;                                    ///< Image width.
  int height = 0;                                   ///< Image height.
  int tile_size = kDefaultTileSize;                 ///< Tile edge.
  bool resumable = false;                           ///< Tiles carry their exact sums (see JobSubmission).
};
void to_json(nlohmann::json& j, const JobSpec& s);
/// Reads a spec (extra keys are ignored); throws ProtocolError naming the field.
void from_json(const nlohmann::json& j, JobSpec& s);

/// Body of POST /v1/blobs: which of these blobs does the coordinator lack? Each one it holds starts its grace period
/// again, as a HEAD of it would, so it stays for the submission that names it.
struct BlobQuery {
  std::vector<std::string> sha256;  ///< Blobs (64 lowercase hex digits each), at most kMaxBlobQuery.
};
inline constexpr size_t kMaxBlobQuery = 4096;  ///< The most blobs one query may name.
void to_json(nlohmann::json& j, const BlobQuery& q);
/// Parses a blob query; throws ProtocolError (400) naming the first bad entry.
BlobQuery parse_blob_query(const std::string& body);

/// Answer 200 to POST /v1/blobs.
struct BlobQueryAnswer {
  std::vector<std::string> missing;  ///< The queried blobs that are not stored, in the query's order.
};
void to_json(nlohmann::json& j, const BlobQueryAnswer& a);
void from_json(const nlohmann::json& j, BlobQueryAnswer& a);

/// Body of POST /v1/workers.
struct WorkerHello {
  std::string name;     ///< Self-reported name.
  int64_t threads = 0;  ///< Render threads.
  std::string version;  ///< Tessera version.
  std::vector<std::string> tags;  ///< What it offers (protocol/tags.h): jobs requiring tags go to workers having them.
};
void to_json(nlohmann::json& j, const WorkerHello& h);
/// Parses a registration request; throws ProtocolError (400).
WorkerHello parse_worker_hello(const std::string& body);

/// Answer 201 to POST /v1/workers.
struct Registration {
  std::string id;                                               ///< Worker id (w-…).
  double lease_seconds = kDefaultLeaseSeconds;                  ///< Lease length.
  double heartbeat_seconds = kDefaultHeartbeatSeconds;          ///< Heartbeat period.
  /// The worker's secret: every later request acting as this worker carries it (kWorkerSecretHeader). The
  /// coordinator keeps only its SHA-256.
  std::string secret;
};
void to_json(nlohmann::json& j, const Registration& r);
void from_json(const nlohmann::json& j, Registration& r);

/// A granted lease: answer 200 to POST /v1/workers/{wid}/lease, and the coordinator's record of it.
struct Lease {
  std::string id;           ///< Lease id (l-…).
  std::string job;          ///< Job id.
  std::string worker;       ///< Worker holding it (the coordinator's bookkeeping; not sent).
  int64_t tile = 0;         ///< Tile number.
  PixelWindow window;       ///< Tile pixels, half-open, row 0 at the top.
  uint32_t spp = 0;         ///< Samples per pixel.
  uint64_t seed = 0;        ///< Sample seed.
  std::string scene_hash;   ///< Scene content hash (informative).
  int64_t deadline_ms = 0;  ///< Expiry unless extended by a heartbeat.
  bool resumable = false;   ///< Upload the tile with its exact sums (core/render/render_state.h channels).
  /// When > 0: the tile was rendered before at this spp; continue from its state, GET /v1/leases/{lease}/state.
  uint32_t state_spp = 0;
};
void to_json(nlohmann::json& j, const Lease& l);
void from_json(const nlohmann::json& j, Lease& l);

/// Body of POST /v1/workers/{wid}/lease (optional: an empty body, or {}, asks for a bare lease).
struct LeaseRequest {
  /// Present: the worker takes the job's spec inside the answer (LeaseAnswer::spec) unless the job is listed here,
  /// the jobs whose specs it holds (at most kMaxKnownJobs). Absent: the answer never carries a spec.
  std::optional<std::vector<std::string>> known_jobs;
  /// Milliseconds the coordinator may hold the request while it has no tile for this worker, answering as soon as
  /// one becomes leasable (0: answer at once).
  int64_t wait_ms = 0;
};
inline constexpr size_t kMaxKnownJobs = 64;       ///< The most jobs a lease request may list as known.
inline constexpr int64_t kMaxLeaseWaitMs = 10000;  ///< The longest wait_ms a lease request may ask for.
void to_json(nlohmann::json& j, const LeaseRequest& r);
/// Parses a lease request; throws ProtocolError (400).
LeaseRequest parse_lease_request(const std::string& body);
/// The kNextLeaseHeader value of a result upload that asks for its worker's next lease as `r` asks for it (its wait_ms
/// is not sent: an upload's answer is never held).
std::string next_lease_header(const LeaseRequest& r);
/// The lease request of a kNextLeaseHeader value, or nothing for "" (no header); throws ProtocolError (400) for a
/// value that is no lease request or asks to wait.
std::optional<LeaseRequest> parse_next_lease_header(std::string_view value);

/// Answer 200 to POST /v1/workers/{wid}/lease: the lease, with its job's spec when the request asked for it.
struct LeaseAnswer {
  Lease lease;                  ///< The lease (its keys at the top level of the answer).
  std::optional<JobSpec> spec;  ///< Key "spec": the job's spec, as GET /v1/jobs/{id}/spec answers it.
};
void to_json(nlohmann::json& j, const LeaseAnswer& a);
void from_json(const nlohmann::json& j, LeaseAnswer& a);
/// The answer's text from the lease and, when to be sent, the spec's JSON text as GET /v1/jobs/{id}/spec answers it
/// (a coordinator keeps that text per job, so no spec is serialised per lease).
std::string lease_answer_text(const Lease& l, const std::string* spec_json);

/// Body of POST /v1/leases/{lease}/heartbeat.
struct HeartbeatReport {
  uint64_t rays = 0;  ///< Rays traced since the previous heartbeat.
};
void to_json(nlohmann::json& j, const HeartbeatReport& h);
HeartbeatReport parse_heartbeat_report(const std::string& body);

/// Answer 200 to POST /v1/leases/{lease}/heartbeat.
struct HeartbeatAnswer {
  int64_t deadline_ms = 0;  ///< The lease's new expiry (coordinator clock, ms since the epoch).
};
void to_json(nlohmann::json& j, const HeartbeatAnswer& a);
void from_json(const nlohmann::json& j, HeartbeatAnswer& a);

/// How the coordinator settled a tile result upload.
enum class UploadStatus {
  accepted,   ///< Stored (answer 200).
  duplicate,  ///< The tile was stored before, by this lease or another (answer 200).
  discarded,  ///< The job was cancelled or failed meanwhile (answer 410).
};
/// The name of each status (the result answer's "status"), in declaration order.
inline constexpr std::string_view kUploadStatusNames[] = {"accepted", "duplicate", "discarded"};
/// The name of a status.
inline const char* to_string(UploadStatus s) { return enum_c_name(s, kUploadStatusNames); }
/// Throws ProtocolError for a name that is none of the statuses.
UploadStatus upload_status_from_string(const std::string& name);

/// Answer to PUT /v1/leases/{lease}/result (200 accepted or duplicate, 410 discarded).
struct ResultAnswer {
  UploadStatus status = UploadStatus::accepted;  ///< How the upload was settled.
  /// Key "next": the worker's next lease, as POST /v1/workers/{wid}/lease answers it. Only when the upload asked for
  /// one (kNextLeaseHeader), was settled accepted or duplicate, and a tile was leasable by the worker; absent, the
  /// worker asks for its next lease as usual.
  std::optional<LeaseAnswer> next;
};
void to_json(nlohmann::json& j, const ResultAnswer& a);
void from_json(const nlohmann::json& j, ResultAnswer& a);
/// The answer's text from its status and, when a next lease was granted, that lease's answer text (lease_answer_text,
/// so no lease or spec is serialised twice).
std::string result_answer_text(UploadStatus status, const std::string* next_lease_text);

/// Body of POST /v1/leases/{lease}/fail.
struct FailReport {
  std::string error = "(no error text)";  ///< What went wrong.
  std::vector<std::string> log;           ///< The worker's last log lines about the lease (see protocol/tile.h bounds).
};
void to_json(nlohmann::json& j, const FailReport& f);
FailReport parse_fail_report(const std::string& body);

/// Answer 200 to POST /v1/leases/{lease}/fail.
struct FailAnswer {
  std::string status = "recorded";  ///< Always "recorded".
};
void to_json(nlohmann::json& j, const FailAnswer& a);
void from_json(const nlohmann::json& j, FailAnswer& a);

/// Answer 200 to POST /v1/leases/{lease}/release.
struct ReleaseAnswer {
  std::string status = "released";  ///< Always "released".
};
void to_json(nlohmann::json& j, const ReleaseAnswer& a);
void from_json(const nlohmann::json& j, ReleaseAnswer& a);

/// The free space of the coordinator's data folder (docs/operations.md, "Disk full").
enum class DiskState {
  ok,    ///< At least `serve --min-free-disk` free.
  low,   ///< Less than that free: submissions and blob uploads are refused (507).
  full,  ///< A write failed for want of space: leases and tile uploads are refused too (507) until writes succeed again.
};
/// The name of each disk state (the health answer's "disk"), in declaration order.
inline constexpr std::string_view kDiskStateNames[] = {"ok", "low", "full"};
/// The name of a disk state.
inline const char* to_string(DiskState s) { return enum_c_name(s, kDiskStateNames); }
/// Throws ProtocolError for a name that is none of the disk states.
DiskState disk_state_from_string(const std::string& name);

/// Answer 200 to GET /healthz (also while the disk is full: the coordinator still serves every read).
struct HealthAnswer {
  std::string status = "ok";       ///< "ok", or "degraded" while `disk` is not ok.
  DiskState disk = DiskState::ok;  ///< The data folder's free space.
  uint64_t disk_free_bytes = 0;    ///< Bytes free on the data folder's file system.
  uint64_t min_free_disk = 0;      ///< `serve --min-free-disk` in bytes.
};
void to_json(nlohmann::json& j, const HealthAnswer& a);
void from_json(const nlohmann::json& j, HealthAnswer& a);

/// Answer 200 or 201 to PUT /v1/blobs/{sha256}.
struct BlobPutAnswer {
  std::string sha256;  ///< The stored blob.
  uint64_t size = 0;   ///< Its size in bytes.
};
void to_json(nlohmann::json& j, const BlobPutAnswer& a);
void from_json(const nlohmann::json& j, BlobPutAnswer& a);

/// The body of every refusal (4xx and 5xx with a JSON body).
struct ErrorAnswer {
  std::string error;  ///< What was wrong, as a sentence.
};
void to_json(nlohmann::json& j, const ErrorAnswer& a);
void from_json(const nlohmann::json& j, ErrorAnswer& a);
/// The refusal's JSON text; bytes of `error` that are not UTF-8 become U+FFFD (it may quote a request target).
std::string error_text(const ErrorAnswer& a);

/// Answer of GET /monitor/capabilities.json: what the web monitor may offer on this coordinator.
struct Capabilities {
  bool tokens_required = false;         ///< The page asks for the client token before its first call.
  std::map<std::string, bool> endpoints;  ///< Monitor control (e.g. "pause") -> the coordinator has its route.
};
void to_json(nlohmann::json& j, const Capabilities& c);
void from_json(const nlohmann::json& j, Capabilities& c);
/// The capabilities of this protocol: every control a route's method names (protocol/routes.h).
Capabilities capabilities(bool tokens_required);

/// Body of a POST that carries nothing (release, retry): empty or {}; throws ProtocolError for anything else.
void parse_empty_request(const std::string& body);

/// Answer of GET /v1/jobs.
struct JobList {
  std::vector<JobStatus> jobs;  ///< Newest first.
  std::optional<std::string> next;  ///< The cursor of the next page (`after=`); null when this page is the last.
};
void to_json(nlohmann::json& j, const JobList& l);
void from_json(const nlohmann::json& j, JobList& l);

/// Answer of GET /v1/jobs/{id}/frames: one page of a sequence's frames, each a job of its own, in frame order.
struct FrameList {
  std::vector<JobStatus> frames;    ///< The frames' jobs (JobStatus::frame is the number), lowest number first.
  std::optional<int64_t> next;      ///< The `after` of the next page (the last number here); null on the last page.
};
void to_json(nlohmann::json& j, const FrameList& l);
void from_json(const nlohmann::json& j, FrameList& l);

/// Answer of DELETE /v1/jobs/{id}?purge=true.
struct PurgeAnswer {
  std::string id;                 ///< The purged job.
  JobState was = JobState::done;  ///< The state it had.
};
void to_json(nlohmann::json& j, const PurgeAnswer& a);
void from_json(const nlohmann::json& j, PurgeAnswer& a);

/// Reads an answer body as T (JSON text, then from_json); throws ProtocolError naming `what`.
template <class T>
T parse_answer(const std::string& body, const std::string& what) {
  const nlohmann::json j = parse_body(body, what);
  try {
    return j.get<T>();
  } catch (const nlohmann::json::exception& e) {
    throw ProtocolError(what + ": " + e.what());
  }
}

}  // namespace tessera::protocol
