// Prints the JSON form of every protocol type that goes on the wire, for tests/openapi/check_types.py to compare with
// docs/openapi.yaml. The output is one object: schema name (components/schemas) -> C++ type -> {"answer", "full",
// "minimal"}. "full" is a sample with every optional field set and every list non-empty, so it holds every key the code
// can write; "minimal" is a default-constructed value, so it holds the keys the code always writes. "answer" is true
// for what the coordinator writes (its always-written keys are exactly the schema's required ones) and false for
// request bodies and parts of them (whose required keys are what the coordinator insists on).
#include "protocol/events.h"
#include "protocol/job.h"
#include "protocol/access.h"
#include "protocol/audit.h"
#include "protocol/messages.h"
#include "protocol/tile.h"
#include "protocol/webhook.h"
#include "protocol/worker.h"

#include <nlohmann/json.hpp>

#include <iostream>
#include <string>
#include <vector>

namespace tessera::protocol {
namespace {

using nlohmann::json;

const std::string kSha = std::string(64, 'a');

// The full samples name every field of their type: GCC's -Wmissing-field-initializers (in -Wextra; an error with
// TESSERA_WERROR) reports a field added to a type but not to its sample.

SamplingSettings full_sampling() {
  return {.spp = 4, .seed = 7, .integrator = "direct", .target_error = 0.05, .min_spp = 8, .max_spp = 64,
          .error_floor = 0.02, .replicates = 2, .area_sampling = "area", .env_sampling = "cosine", .bvh = "median",
          .layers = parse_layers("albedo,normal,depth,crypto_object")};
}

// per_frame, the movie step (and its fps) and notify_frames apply to a sequence only.
Pipeline full_pipeline(bool sequence) {
  if (!sequence)
    return {.after = {"j-0"}, .per_frame = false, .then = {Step::preview, Step::half},
            .fps = kDefaultMovieFps, .notify = "https://hooks.example/tessera", .notify_frames = false};
  return {.after = {"j-0"}, .per_frame = true, .then = {Step::preview, Step::contact_sheet, Step::movie},
          .fps = 12, .notify = "https://hooks.example/tessera", .notify_frames = true};
}

json sample_scene() { return {{"film", {{"resolution", {16, 16}}}}}; }

JobSubmission full_submission() {
  return {.scene = sample_scene(), .assets = {{"assets/floor.obj", kSha}},
          .frames = {}, .frame_order = FrameOrder::in_order, .sampling = full_sampling(), .tile_size = 8,
          .priority = 3, .name = "sample", .resumable = true, .tile_timeout_seconds = 60, .require = {"bigmem"},
          .max_workers = 4, .pipeline = full_pipeline(false)};
}

// A sequence's submission: "frames" (with a frame's own assets) and "frame_order" instead of "scene".
JobSubmission full_sequence_submission() {
  JobSubmission s = full_submission();
  s.resumable = false;
  s.frames = {{.number = 1, .scene = sample_scene(), .assets = {{"assets/floor.obj", kSha}}}};
  s.frame_order = FrameOrder::any;
  s.pipeline = full_pipeline(true);
  return s;
}

JobSpec full_spec() {
  return {.scene = sample_scene(), .assets = {{"assets/floor.obj", kSha}}, .sampling = full_sampling(), .width = 16,
          .height = 16, .tile_size = 8, .resumable = true};
}

JobStatus full_job() {
  return {.id = "j-1",
          .params = {.name = "sample", .priority = 3, .width = 16, .height = 16, .tile_size = 8, .spp = 4, .seed = 7,
                     .scene_hash = "hash", .tile_timeout_seconds = 60, .frame_order = FrameOrder::any,
                     .owner = "ana", .require = {"bigmem"}, .max_workers = 4, .pipeline = full_pipeline(true)},
          .state = JobState::failed,
          .tiles = {.total = 4, .done = 1, .leased = 1, .pending = 2},
          .created_ms = 1000,
          .started_ms = 2000,
          .finished_ms = 3000,
          .error = "a tile failed on 3 workers",
          .rays = 123,
          .workers = {"w-1"},
          .render_seconds = 1.5,
          .frames = FrameCounts{.total = 3, .queued = 1, .running = 1, .paused = 0, .done = 1, .failed = 0,
                                .cancelled = 0, .waiting = 0, .blocked = 0, .first = 1, .last = 3},
          .sequence = "j-0",
          .frame = 2,
          .waiting_for = "a worker with tags bigmem",
          .dependents = {"j-5"},
          .reason = "dependency j-0 failed: a tile failed on 3 workers",
          .outputs = {{.step = Step::preview, .state = "done", .files = {"preview.png"}, .log = ""}}};
}

Lease full_lease() {
  return {.id = "l-1", .job = "j-1", .worker = "w-1", .tile = 2, .window = {8, 0, 16, 8}, .spp = 4, .seed = 7,
          .scene_hash = "hash", .deadline_ms = 5000, .resumable = true, .state_spp = 2};
}

WorkerInfo full_worker() {
  return {.id = "w-1", .name = "host-1", .state = WorkerState::rendering, .job = "j-1", .tile = 2, .threads = 8,
          .tiles_done = 5, .rays = 456, .render_seconds = 2.5, .last_seen_ms = 4000, .blocklisted_for = {"j-2"},
          .tags = {"bigmem", "gpu"}};
}

TileFailure full_failure() {
  return {.worker = "w-2", .worker_name = "host-2", .error = "out of memory", .log = {"a log line"}};
}

TileInfo full_tile() {
  return {.index = 2, .window = {8, 0, 16, 8}, .state = "leased", .worker = "w-1", .worker_name = "host-1",
          .attempts = 2, .render_seconds = 0.5, .rays = 789, .rendered_by = "w-3", .rendered_by_name = "host-3",
          .failures = {full_failure()}, .log = {"rendered in 0.5s"}, .log_not_kept = true};
}

// One entry of the output: out[schema][type].
void add(json& out, const char* schema, const char* type, bool answer, const json& full, const json& minimal) {
  out[schema][type] = {{"answer", answer}, {"full", full}, {"minimal", minimal}};
}

json dump() {
  constexpr bool kAnswer = true, kRequest = false;
  json out = json::object();
  add(out, "Sampling", "SamplingSettings", kRequest, full_sampling(), SamplingSettings{});
  add(out, "JobSubmission", "JobSubmission", kRequest, full_submission(), JobSubmission{});
  JobSubmission minimal_sequence;
  minimal_sequence.frames = {FrameSubmission{}};
  add(out, "JobSubmission", "JobSubmission (sequence)", kRequest, full_sequence_submission(), minimal_sequence);
  add(out, "RetryRequest", "RetryRequest", kRequest, RetryRequest{{1, 2}}, RetryRequest{});
  const WebhookDelivery delivery{.id = "e-1", .url = "https://hooks.example/t", .event = "job.done", .job = "j-1",
                                 .state = "pending", .attempts = 2, .created_ms = 1000, .next_ms = 5000,
                                 .last_status = 500, .last_error = "answered 500"};
  add(out, "WebhookDelivery", "WebhookDelivery", kAnswer, delivery, WebhookDelivery{});
  add(out, "WebhookDeliveryList", "WebhookDeliveryList", kAnswer, WebhookDeliveryList{{delivery}}, WebhookDeliveryList{});
  add(out, "JobPatch", "JobPatch", kRequest, JobPatch{3, 8}, JobPatch{});
  add(out, "SubmitAnswer", "SubmitAnswer", kAnswer, SubmitAnswer{"j-1", {"a warning"}}, SubmitAnswer{});
  add(out, "JobSpec", "JobSpec", kAnswer, full_spec(), JobSpec{});
  add(out, "Job", "JobStatus", kAnswer, full_job(), JobStatus{});
  add(out, "JobList", "JobList", kAnswer, JobList{{full_job()}, "c1"}, JobList{});
  add(out, "FrameList", "FrameList", kAnswer, FrameList{{full_job()}, 2}, FrameList{});
  add(out, "PurgeAnswer", "PurgeAnswer", kAnswer, PurgeAnswer{"j-1", JobState::cancelled}, PurgeAnswer{});
  add(out, "BlobQuery", "BlobQuery", kRequest, BlobQuery{{kSha}}, BlobQuery{});
  add(out, "BlobQueryAnswer", "BlobQueryAnswer", kAnswer, BlobQueryAnswer{{kSha}}, BlobQueryAnswer{});
  add(out, "BlobStored", "BlobPutAnswer", kAnswer, BlobPutAnswer{kSha, 42}, BlobPutAnswer{});
  add(out, "WorkerHello", "WorkerHello", kRequest, WorkerHello{"host-1", 8, "0.1.0", {"gpu"}}, WorkerHello{});
  add(out, "Registration", "Registration", kAnswer, Registration{"w-1", 0.5, 5, "9f86d081884c7d65"}, Registration{});
  add(out, "Worker", "WorkerInfo", kAnswer, full_worker(), WorkerInfo{});
  add(out, "WorkerList", "WorkerList", kAnswer, WorkerList{{full_worker()}}, WorkerList{});
  // The lease answer: the lease's keys with the job's spec beside them, as the coordinator writes it.
  const std::string spec_text = json(full_spec()).dump();
  add(out, "Lease", "Lease", kAnswer, json::parse(lease_answer_text(full_lease(), &spec_text)),
      json::parse(lease_answer_text(Lease{}, nullptr)));
  add(out, "LeaseRequest", "LeaseRequest", kRequest, LeaseRequest{std::vector<std::string>{"j-1"}, 100}, LeaseRequest{});
  add(out, "HeartbeatReport", "HeartbeatReport", kRequest, HeartbeatReport{10}, HeartbeatReport{});
  add(out, "HeartbeatAnswer", "HeartbeatAnswer", kAnswer, HeartbeatAnswer{5000}, HeartbeatAnswer{});
  // An upload's answer with the next lease it asked for (X-Tessera-Next-Lease): the lease answer above under "next".
  add(out, "UploadStatus", "ResultAnswer", kAnswer,
      ResultAnswer{UploadStatus::duplicate, LeaseAnswer{full_lease(), full_spec()}}, ResultAnswer{});
  add(out, "FailReport", "FailReport", kRequest, FailReport{"it broke", {"a log line"}}, FailReport{});
  add(out, "Status", "FailAnswer", kAnswer, FailAnswer{}, FailAnswer{});
  add(out, "Status", "ReleaseAnswer", kAnswer, ReleaseAnswer{}, ReleaseAnswer{});
  add(out, "Health", "HealthAnswer", kAnswer, HealthAnswer{}, HealthAnswer{});
  add(out, "Error", "ErrorAnswer", kAnswer, ErrorAnswer{"what was wrong"}, ErrorAnswer{});
  add(out, "Capabilities", "Capabilities", kAnswer, capabilities(true), Capabilities{});
  add(out, "Tags", "tags", kRequest, json(std::vector<std::string>{"bigmem", "gpu"}), json::array());
  add(out, "Me", "Me", kAnswer, me_for("ana", Role::user), Me{});
  const AuditEntry entry{7, 5000, "ana", "user", "POST /v1/jobs/{id}/pause", "j-1", "127.0.0.1", 200};
  add(out, "AuditEntry", "AuditEntry", kAnswer, entry, AuditEntry{});
  add(out, "AuditList", "AuditList", kAnswer, AuditList{{entry}, 6}, AuditList{});
  add(out, "TileFailure", "TileFailure", kAnswer, full_failure(), TileFailure{});
  add(out, "Tile", "TileInfo", kAnswer, full_tile(), TileInfo{});
  add(out, "TileList", "TileList", kAnswer, TileList{"j-1", {full_tile()}, 3}, TileList{});
  add(out, "TileEvent", "TileEvent", kAnswer, TileEvent{"j-1", 2, "w-1", "l-1", "it broke"}, TileEvent{});
  add(out, "FrameEvent", "FrameEvent", kAnswer, FrameEvent{"j-1", 2, "j-1.f2"}, FrameEvent{});
  add(out, "WorkerEvent", "WorkerEvent", kAnswer, WorkerEvent{"registered", full_worker()}, WorkerEvent{});
  return out;
}

}  // namespace
}  // namespace tessera::protocol

int main() {
  std::cout << tessera::protocol::dump().dump(2) << '\n';
  return 0;
}
