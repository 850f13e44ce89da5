#include "protocol/worker.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

#include <stdexcept>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const WorkerInfo& w) {
  j = {{"id", w.id},
       {"name", w.name},
       {"state", to_string(w.state)},
       {"job", w.job ? json(*w.job) : json(nullptr)},
       {"tile", w.tile ? json(*w.tile) : json(nullptr)},
       {"threads", w.threads},
       {"tiles_done", w.tiles_done},
       {"rays", w.rays},
       {"render_seconds", w.render_seconds},
       {"last_seen_ms", w.last_seen_ms},
       {"blocklisted_for", w.blocklisted_for},
       {"tags", w.tags}};
}

void from_json(const json& j, WorkerInfo& w) {
  constexpr const char* kMsg = "worker";
  w = WorkerInfo{};
  w.id = answer_field<std::string>(j, "id", kMsg);
  w.name = answer_field_or<std::string>(j, "name", kMsg, "");
  try {
    w.state = worker_state_from_string(answer_field<std::string>(j, "state", kMsg));
  } catch (const std::invalid_argument& e) {
    throw ProtocolError(std::string(kMsg) + ": " + e.what());
  }
  if (j.contains("job") && !j["job"].is_null()) w.job = answer_field<std::string>(j, "job", kMsg);
  if (j.contains("tile") && !j["tile"].is_null()) w.tile = answer_field<int64_t>(j, "tile", kMsg);
  w.threads = answer_field_or<int64_t>(j, "threads", kMsg, 0);
  w.tiles_done = answer_field_or<int64_t>(j, "tiles_done", kMsg, 0);
  w.rays = answer_field_or<uint64_t>(j, "rays", kMsg, 0);
  w.render_seconds = answer_field_or<double>(j, "render_seconds", kMsg, 0.0);
  w.last_seen_ms = answer_field_or<int64_t>(j, "last_seen_ms", kMsg, 0);
  w.blocklisted_for = answer_field_or<std::vector<std::string>>(j, "blocklisted_for", kMsg, {});
  w.tags = answer_field_or<std::vector<std::string>>(j, "tags", kMsg, {});
}

void to_json(json& j, const WorkerList& l) { j = {{"workers", l.workers}}; }

void from_json(const json& j, WorkerList& l) { l.workers = answer_field<std::vector<WorkerInfo>>(j, "workers", "worker list"); }

}  // namespace tessera::protocol
