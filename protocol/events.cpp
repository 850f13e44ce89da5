#include "protocol/events.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const TileEvent& e) {
  j = {{"job", e.job}, {"tile", e.tile}, {"worker", e.worker}};
  if (e.lease) j["lease"] = *e.lease;
  if (e.error) j["error"] = *e.error;
}

void from_json(const json& j, TileEvent& e) {
  constexpr const char* kMsg = "tile event";
  e = TileEvent{};
  e.job = answer_field<std::string>(j, "job", kMsg);
  e.tile = answer_field<int64_t>(j, "tile", kMsg);
  e.worker = answer_field_or<std::string>(j, "worker", kMsg, "");
  if (j.contains("lease") && !j["lease"].is_null()) e.lease = answer_field<std::string>(j, "lease", kMsg);
  if (j.contains("error") && !j["error"].is_null()) e.error = answer_field<std::string>(j, "error", kMsg);
}

void to_json(json& j, const FrameEvent& e) { j = {{"job", e.job}, {"frame", e.frame}, {"frame_job", e.frame_job}}; }

void from_json(const json& j, FrameEvent& e) {
  constexpr const char* kMsg = "frame event";
  e.job = answer_field<std::string>(j, "job", kMsg);
  e.frame = answer_field<int64_t>(j, "frame", kMsg);
  e.frame_job = answer_field<std::string>(j, "frame_job", kMsg);
}

void to_json(json& j, const WorkerEvent& e) { j = {{"reason", e.reason}, {"worker", e.worker}}; }

void from_json(const json& j, WorkerEvent& e) {
  e.reason = answer_field<std::string>(j, "reason", "worker event");
  e.worker = answer_field<WorkerInfo>(j, "worker", "worker event");
}

}  // namespace tessera::protocol
