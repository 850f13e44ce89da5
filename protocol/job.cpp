#include "protocol/job.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

#include <stdexcept>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const JobStatus& s) {
  j = {{"id", s.id},
       {"name", s.params.name},
       {"state", to_string(s.state)},
       {"priority", s.params.priority},
       {"width", s.params.width},
       {"height", s.params.height},
       {"spp", s.params.spp},
       {"seed", s.params.seed},
       {"tile_size", s.params.tile_size},
       {"scene_hash", s.params.scene_hash},
       {"tile_timeout_seconds", s.params.tile_timeout_seconds},
       {"tiles", {{"total", s.tiles.total}, {"done", s.tiles.done}, {"leased", s.tiles.leased}, {"pending", s.tiles.pending}}},
       {"created_ms", s.created_ms},
       {"started_ms", optional_json(s.started_ms)},
       {"finished_ms", optional_json(s.finished_ms)},
       {"render_seconds", s.render_seconds},
       {"rays", s.rays},
       {"workers", s.workers},
       {"error", optional_json(s.error)}};
  if (s.frames) {
    j["frames"] = *s.frames;
    j["frame_order"] = to_string(s.params.frame_order);
  }
  if (s.sequence) j["sequence"] = *s.sequence;
  if (s.frame) j["frame"] = *s.frame;
  j["owner"] = s.params.owner;
  j["require"] = s.params.require;
  j["max_workers"] = s.params.max_workers;
  j["waiting_for"] = optional_json(s.waiting_for);
  put_pipeline(j, s.params.pipeline);
  if (!s.dependents.empty()) j["dependents"] = s.dependents;
  if (s.reason) j["reason"] = *s.reason;
  if (!s.outputs.empty()) j["outputs"] = s.outputs;
}

void from_json(const json& j, JobStatus& s) {
  constexpr const char* kMsg = "job";
  s = JobStatus{};
  s.id = answer_field<std::string>(j, "id", kMsg);
  const auto state = answer_field<std::string>(j, "state", kMsg);
  try {
    s.state = job_state_from_string(state);
  } catch (const std::invalid_argument& e) {
    throw ProtocolError(std::string(kMsg) + ": " + e.what());
  }
  JobParams& p = s.params;
  p.name = answer_field_or<std::string>(j, "name", kMsg, "");
  p.priority = answer_field_or<int>(j, "priority", kMsg, kDefaultPriority);
  p.width = answer_field_or<int>(j, "width", kMsg, 0);
  p.height = answer_field_or<int>(j, "height", kMsg, 0);
  p.spp = answer_field_or<uint32_t>(j, "spp", kMsg, 1);
  p.seed = answer_field_or<uint64_t>(j, "seed", kMsg, 0);
  p.tile_size = answer_field_or<int>(j, "tile_size", kMsg, kDefaultTileSize);
  p.scene_hash = answer_field_or<std::string>(j, "scene_hash", kMsg, "");
  p.tile_timeout_seconds = answer_field_or<int64_t>(j, "tile_timeout_seconds", kMsg, kDefaultTileTimeoutSeconds);
  if (j.contains("tiles") && j["tiles"].is_object()) {
    const json& t = j["tiles"];
    s.tiles.total = answer_field_or<int64_t>(t, "total", "job tiles", 0);
    s.tiles.done = answer_field_or<int64_t>(t, "done", "job tiles", 0);
    s.tiles.leased = answer_field_or<int64_t>(t, "leased", "job tiles", 0);
    s.tiles.pending = answer_field_or<int64_t>(t, "pending", "job tiles", 0);
  }
  s.created_ms = answer_field_or<int64_t>(j, "created_ms", kMsg, 0);
  if (j.contains("started_ms") && !j["started_ms"].is_null()) s.started_ms = answer_field<int64_t>(j, "started_ms", kMsg);
  if (j.contains("finished_ms") && !j["finished_ms"].is_null())
    s.finished_ms = answer_field<int64_t>(j, "finished_ms", kMsg);
  if (j.contains("error") && !j["error"].is_null()) s.error = answer_field<std::string>(j, "error", kMsg);
  s.rays = answer_field_or<uint64_t>(j, "rays", kMsg, 0);
  s.workers = answer_field_or<std::vector<std::string>>(j, "workers", kMsg, {});
  s.render_seconds = answer_field_or<double>(j, "render_seconds", kMsg, 0);
  if (j.contains("frames") && !j["frames"].is_null()) {
    if (!j["frames"].is_object()) throw ProtocolError(std::string(kMsg) + ": \"frames\" is not an object");
    s.frames = j["frames"].get<FrameCounts>();
  }
  try {
    p.frame_order = frame_order_from_string(answer_field_or<std::string>(j, "frame_order", kMsg, "in_order"));
  } catch (const std::invalid_argument& e) {
    throw ProtocolError(std::string(kMsg) + ": " + e.what());
  }
  if (j.contains("sequence") && !j["sequence"].is_null()) s.sequence = answer_field<std::string>(j, "sequence", kMsg);
  if (j.contains("frame") && !j["frame"].is_null()) s.frame = answer_field<int64_t>(j, "frame", kMsg);
  p.owner = answer_field_or<std::string>(j, "owner", kMsg, "");
  p.require = answer_field_or<std::vector<std::string>>(j, "require", kMsg, {});
  p.max_workers = answer_field_or<int64_t>(j, "max_workers", kMsg, 0);
  if (j.contains("waiting_for") && !j["waiting_for"].is_null())
    s.waiting_for = answer_field<std::string>(j, "waiting_for", kMsg);
  p.pipeline = answer_pipeline(j);
  s.dependents = answer_field_or<std::vector<std::string>>(j, "dependents", kMsg, {});
  if (j.contains("reason") && !j["reason"].is_null()) s.reason = answer_field<std::string>(j, "reason", kMsg);
  s.outputs = answer_field_or<std::vector<StepOutput>>(j, "outputs", kMsg, {});
}

}  // namespace tessera::protocol
