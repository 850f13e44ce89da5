#include "core/scene/scene_json.h"

#include <algorithm>
#include <cmath>

namespace tessera {

using json = nlohmann::json;

std::string join_names(const std::vector<std::string>& v) {
  std::string out;
  for (size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + v[i];
  return out;
}

void SceneJson::fail(const std::string& path, const std::string& msg) const {
  throw SceneError(name + ": " + path + ": " + msg);
}

void SceneJson::warn(const std::string& path, const std::string& msg) {
  if (opt.strict) fail(path, msg + " (--strict)");
  out.warnings.push_back(name + ": " + path + ": " + msg);
}

const json& SceneJson::object(const json& j, const std::string& path) const {
  if (!j.is_object()) fail(path, std::string("expected an object, got ") + j.type_name());
  return j;
}

void SceneJson::check_keys(const json& j, const std::string& path, std::span<const char* const> known,
                           std::span<const char* const> other) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    if (std::any_of(known.begin(), known.end(), [&](const char* s) { return k == s; })) continue;
    if (std::any_of(other.begin(), other.end(), [&](const char* s) { return k == s; })) {
      out.notes.push_back(name + ": " + path + "." + k + " is used by other integrators only; ignored");
      continue;
    }
    std::vector<std::string> names(known.begin(), known.end());
    warn(path + "." + k, "unknown key (known here: " + join_names(names) + ")");
  }
}

double SceneJson::checked(double d, const std::string& path) const {
  if (!std::isfinite(d)) fail(path, "must be finite");
  if (!std::isfinite(float(d))) fail(path, "is out of the float range (|value| > 3.4e38)");
  return d;
}

double SceneJson::number(const json& j, const char* key, const std::string& path, double def) const {
  if (!j.contains(key)) return def;
  const json& v = j.at(key);
  if (!v.is_number()) fail(path + "." + key, std::string("expected a number, got ") + v.type_name());
  return checked(v.get<double>(), path + "." + key);
}

std::string SceneJson::string(const json& j, const char* key, const std::string& path, const char* def) const {
  if (!j.contains(key)) {
    if (def) return def;
    fail(path + "." + key, "missing");
  }
  const json& v = j.at(key);
  if (!v.is_string()) fail(path + "." + key, std::string("expected a string, got ") + v.type_name());
  return v.get<std::string>();
}

std::vector<double> SceneJson::numbers(const json& v, const std::string& path, size_t n) const {
  if (!v.is_array() || v.size() != n) fail(path, "expected an array of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (size_t i = 0; i < n; ++i) {
    if (!v[i].is_number()) fail(path + "[" + std::to_string(i) + "]", "expected a number");
    out.push_back(checked(v[i].get<double>(), path + "[" + std::to_string(i) + "]"));
  }
  return out;
}

Vec3 SceneJson::vec3(const json& j, const char* key, const std::string& path, const Vec3& def) const {
  return Vec3(dvec3(j, key, path, glm::dvec3(def)));
}

glm::dvec3 SceneJson::dvec3(const json& j, const char* key, const std::string& path, const glm::dvec3& def) const {
  if (!j.contains(key)) return def;
  const auto v = numbers(j.at(key), path + "." + key, 3);
  return glm::dvec3(v[0], v[1], v[2]);
}

Vec3 SceneJson::colour(const json& j, const char* key, const std::string& path, const Vec3& def) const {
  const Vec3 c = vec3(j, key, path, def);
  if (c.x < 0.f || c.y < 0.f || c.z < 0.f) fail(path + "." + key, "must not be negative");
  return c;
}

glm::dmat4 SceneJson::matrix(const json& v, const std::string& path) const {
  std::vector<double> m;
  if (v.is_array() && v.size() == 4 && v[0].is_array()) {
    for (size_t r = 0; r < 4; ++r) {
      const auto row = numbers(v[r], path + "[" + std::to_string(r) + "]", 4);
      m.insert(m.end(), row.begin(), row.end());
    }
  } else {
    m = numbers(v, path, 16);
  }
  glm::dmat4 out(1.0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out[c][r] = m[size_t(r * 4 + c)];  // glm is column-major
  return out;
}

}  // namespace tessera
