#include "worker/protocol.h"

namespace tessera::farm {

using nlohmann::json;

namespace {

// The field `key` of object j converted to T; throws ProtocolError naming the message and field.
template <class T>
T field(const json& j, const char* key, const char* message) {
  if (!j.is_object()) throw ProtocolError(std::string(message) + ": not a JSON object");
  const auto it = j.find(key);
  if (it == j.end()) throw ProtocolError(std::string(message) + ": missing \"" + key + "\"");
  try {
    return it->get<T>();
  } catch (const json::exception& e) {
    throw ProtocolError(std::string(message) + ": \"" + key + "\" has the wrong type (" + e.what() + ")");
  }
}

template <class T>
T optional_field(const json& j, const char* key, const char* message, T fallback) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return fallback;
  return field<T>(j, key, message);
}

}  // namespace

json parse_body(const std::string& body, const std::string& what) {
  json j = json::parse(body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) throw ProtocolError(what + ": the coordinator's answer is not JSON");
  return j;
}

Registration parse_registration(const json& j) {
  Registration r;
  r.id = field<std::string>(j, "id", "registration");
  r.lease_seconds = optional_field<double>(j, "lease_seconds", "registration", 30);
  r.heartbeat_seconds = optional_field<double>(j, "heartbeat_seconds", "registration", 5);
  if (!(r.heartbeat_seconds > 0)) throw ProtocolError("registration: heartbeat_seconds must be positive");
  return r;
}

Lease parse_lease(const json& j) {
  Lease l;
  l.id = field<std::string>(j, "lease", "lease");
  l.job = field<std::string>(j, "job", "lease");
  l.tile = field<int64_t>(j, "tile", "lease");
  const auto w = field<std::vector<int>>(j, "window", "lease");
  if (w.size() != 4) throw ProtocolError("lease: \"window\" must hold 4 numbers");
  l.window = {w[0], w[1], w[2], w[3]};
  if (l.window.empty()) throw ProtocolError("lease: empty window");
  l.spp = field<uint32_t>(j, "spp", "lease");
  l.seed = optional_field<uint64_t>(j, "seed", "lease", 0);
  l.scene_hash = optional_field<std::string>(j, "scene_hash", "lease", "");
  return l;
}

JobSpec parse_job_spec(const json& j) {
  JobSpec s;
  if (!j.is_object() || !j.contains("scene") || !j["scene"].is_object())
    throw ProtocolError("job spec: missing \"scene\" object");
  s.scene = j["scene"];
  s.assets = optional_field<std::map<std::string, std::string>>(j, "assets", "job spec", {});
  s.spp = field<uint32_t>(j, "spp", "job spec");
  s.seed = optional_field<uint64_t>(j, "seed", "job spec", 0);
  s.width = field<int>(j, "width", "job spec");
  s.height = field<int>(j, "height", "job spec");
  s.integrator = optional_field<std::string>(j, "integrator", "job spec", "");
  s.target_error = optional_field<double>(j, "target_error", "job spec", 0.0);
  s.min_spp = optional_field<uint32_t>(j, "min_spp", "job spec", 16);
  s.max_spp = optional_field<uint32_t>(j, "max_spp", "job spec", 1024);
  if (!(s.target_error >= 0.0) || s.min_spp < 1 || s.min_spp > s.max_spp)
    throw ProtocolError("job spec: bad adaptive sampling settings (target_error, min_spp, max_spp)");
  return s;
}

JobStatus parse_job_status(const json& j) {
  JobStatus s;
  s.id = field<std::string>(j, "id", "job");
  s.state = field<std::string>(j, "state", "job");
  s.width = optional_field<int>(j, "width", "job", 0);
  s.height = optional_field<int>(j, "height", "job", 0);
  if (j.contains("tiles") && j["tiles"].is_object()) {
    const json& t = j["tiles"];
    s.tiles_total = optional_field<int64_t>(t, "total", "job tiles", 0);
    s.tiles_done = optional_field<int64_t>(t, "done", "job tiles", 0);
    s.tiles_leased = optional_field<int64_t>(t, "leased", "job tiles", 0);
  }
  s.render_seconds = optional_field<double>(j, "render_seconds", "job", 0);
  s.rays = optional_field<uint64_t>(j, "rays", "job", 0);
  s.error = optional_field<std::string>(j, "error", "job", "");
  return s;
}

}  // namespace tessera::farm
