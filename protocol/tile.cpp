#include "protocol/tile.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const TileFailure& f) {
  j = {{"worker", f.worker}, {"worker_name", f.worker_name}, {"error", f.error}, {"log", f.log}};
}

void from_json(const json& j, TileFailure& f) {
  constexpr const char* kMsg = "tile failure";
  f.worker = answer_field<std::string>(j, "worker", kMsg);
  f.worker_name = answer_field_or<std::string>(j, "worker_name", kMsg, "");
  f.error = answer_field_or<std::string>(j, "error", kMsg, "");
  f.log = answer_field_or<std::vector<std::string>>(j, "log", kMsg, {});
}

void to_json(json& j, const TileInfo& t) {
  j = {{"index", t.index},
       {"window", json::array({t.window.x0, t.window.y0, t.window.x1, t.window.y1})},
       {"state", t.state},
       {"worker", optional_json(t.worker)},
       {"worker_name", optional_json(t.worker_name)},
       {"attempts", t.attempts},
       {"render_seconds", optional_json(t.render_seconds)},
       {"rays", t.rays},
       {"rendered_by", optional_json(t.rendered_by)},
       {"rendered_by_name", optional_json(t.rendered_by_name)},
       {"failures", t.failures},
       {"log", t.log},
       {"log_not_kept", t.log_not_kept}};
}

void from_json(const json& j, TileInfo& t) {
  constexpr const char* kMsg = "tile";
  t = TileInfo{};
  t.index = answer_field<int64_t>(j, "index", kMsg);
  t.state = answer_field<std::string>(j, "state", kMsg);
  const auto w = answer_field_or<std::vector<int>>(j, "window", kMsg, {});
  if (!w.empty() && w.size() != 4) throw ProtocolError("tile: \"window\" must hold 4 numbers");
  if (w.size() == 4) t.window = {w[0], w[1], w[2], w[3]};
  if (j.contains("worker") && !j["worker"].is_null()) t.worker = answer_field<std::string>(j, "worker", kMsg);
  if (j.contains("worker_name") && !j["worker_name"].is_null())
    t.worker_name = answer_field<std::string>(j, "worker_name", kMsg);
  t.attempts = answer_field_or<int64_t>(j, "attempts", kMsg, 0);
  if (j.contains("render_seconds") && !j["render_seconds"].is_null())
    t.render_seconds = answer_field<double>(j, "render_seconds", kMsg);
  t.rays = answer_field_or<uint64_t>(j, "rays", kMsg, 0);
  if (j.contains("rendered_by") && !j["rendered_by"].is_null())
    t.rendered_by = answer_field<std::string>(j, "rendered_by", kMsg);
  if (j.contains("rendered_by_name") && !j["rendered_by_name"].is_null())
    t.rendered_by_name = answer_field<std::string>(j, "rendered_by_name", kMsg);
  t.failures = answer_field_or<std::vector<TileFailure>>(j, "failures", kMsg, {});
  t.log = answer_field_or<std::vector<std::string>>(j, "log", kMsg, {});
  t.log_not_kept = answer_field_or<bool>(j, "log_not_kept", kMsg, false);
}

void to_json(json& j, const TileList& l) { j = {{"job", l.job}, {"tiles", l.tiles}, {"logs_not_kept", l.logs_not_kept}}; }

void from_json(const json& j, TileList& l) {
  l.job = answer_field_or<std::string>(j, "job", "tile list", "");
  l.tiles = answer_field<std::vector<TileInfo>>(j, "tiles", "tile list");
  l.logs_not_kept = answer_field_or<int64_t>(j, "logs_not_kept", "tile list", 0);
}

}  // namespace tessera::protocol
