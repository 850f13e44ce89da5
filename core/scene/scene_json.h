// Checked reads from a scene's JSON (the parse stage of the scene loader): every value is type- and range-checked,
// unknown keys are warned about (errors with --strict), and every message names the scene and the JSON path.
#pragma once

#include "core/util/enum_names.h"
#include "core/util/math.h"
#include "core/scene/scene_loader.h"

#include <nlohmann/json.hpp>

#include <initializer_list>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

/// "a, b, c".
std::string join_names(const std::vector<std::string>& names);

/// Reads values out of a scene's JSON for one load: failures are SceneErrors "NAME: PATH: what", warnings and notes
/// go to `out`.
struct SceneJson {
  std::string name;      ///< The scene's name (its file), first in every message.
  const LoadOptions& opt;
  LoadedScene& out;      ///< Receives warnings and notes.

  [[noreturn]] void fail(const std::string& path, const std::string& msg) const;
  /// A warning, or with --strict an error.
  void warn(const std::string& path, const std::string& msg);
  /// `j` itself, when it is an object.
  const nlohmann::json& object(const nlohmann::json& j, const std::string& path) const;
  /// Warns about keys outside `known`; keys in `other` belong to other integrators and only produce a note.
  void check_keys(const nlohmann::json& j, const std::string& path, std::span<const char* const> known,
                  std::span<const char* const> other = {});
  void check_keys(const nlohmann::json& j, const std::string& path, std::initializer_list<const char*> known,
                  std::initializer_list<const char*> other = {}) {
    check_keys(j, path, std::span(known.begin(), known.size()), std::span(other.begin(), other.size()));
  }
  /// A number the renderer can hold: finite, and finite again once rounded to float (1e39 is not).
  double checked(double d, const std::string& path) const;
  /// j[key] as a number, `def` when absent.
  double number(const nlohmann::json& j, const char* key, const std::string& path, double def) const;
  /// j[key] as a string, `def` when absent (no default: missing is an error).
  std::string string(const nlohmann::json& j, const char* key, const std::string& path, const char* def = nullptr) const;
  /// An array of exactly n numbers.
  std::vector<double> numbers(const nlohmann::json& v, const std::string& path, size_t n) const;
  Vec3 vec3(const nlohmann::json& j, const char* key, const std::string& path, const Vec3& def) const;
  glm::dvec3 dvec3(const nlohmann::json& j, const char* key, const std::string& path, const glm::dvec3& def) const;
  /// An RGB value that must not be negative.
  Vec3 colour(const nlohmann::json& j, const char* key, const std::string& path, const Vec3& def) const;
  /// A 4x4 matrix as 4 rows of 4 numbers or 16 numbers, row-major.
  glm::dmat4 matrix(const nlohmann::json& v, const std::string& path) const;

  /// One of the names in `names` (an enum's table, core/util/enum_names.h), else `def`; other strings are errors.
  template <class E, size_t N>
  E choice(const nlohmann::json& j, const char* key, const std::string& path, E def,
           const std::string_view (&names)[N]) const {
    if (!j.contains(key)) return def;
    const std::string v = string(j, key, path);
    if (const std::optional<E> e = enum_from_name<E>(v, names)) return *e;
    fail(path + "." + key, "'" + v + "' is not one of: " + join_names(enum_names(names)));
  }
};

}  // namespace tessera
