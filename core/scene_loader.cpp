#include "core/scene_loader.h"

#include "core/camera_frame.h"
#include "core/coincident.h"
#include "core/enum_names.h"
#include "core/image.h"
#include "core/sha256.h"

#include <nlohmann/json.hpp>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace tessera {

using json = nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr int kMaxResolution = 65536;
constexpr uint64_t kMaxPixels = uint64_t(1) << 28;
constexpr uint32_t kMaxSpp = 1u << 20;

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + v[i];
  return out;
}

// Parsing context: names messages after the scene and collects warnings.
struct Ctx {
  std::string name;
  const LoadOptions& opt;
  LoadedScene& out;

  [[noreturn]] void fail(const std::string& path, const std::string& msg) const {
    throw SceneError(name + ": " + path + ": " + msg);
  }
  void warn(const std::string& path, const std::string& msg) {
    if (opt.strict) fail(path, msg + " (--strict)");
    out.warnings.push_back(name + ": " + path + ": " + msg);
  }

  const json& object(const json& j, const std::string& path) const {
    if (!j.is_object()) fail(path, std::string("expected an object, got ") + j.type_name());
    return j;
  }

  // Warns about keys outside `known`; keys in `other` belong to other integrators and only produce a note.
  void check_keys(const json& j, const std::string& path, std::initializer_list<const char*> known,
                  std::initializer_list<const char*> other = {}) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      const std::string& k = it.key();
      if (std::any_of(known.begin(), known.end(), [&](const char* s) { return k == s; })) continue;
      if (std::any_of(other.begin(), other.end(), [&](const char* s) { return k == s; })) {
        out.notes.push_back(name + ": " + path + "." + k + " is used by other integrators only; ignored");
        continue;
      }
      std::vector<std::string> names(known.begin(), known.end());
      warn(path + "." + k, "unknown key (known here: " + join(names) + ")");
    }
  }

  // A number the renderer can hold: finite, and finite again once rounded to float (1e39 is not).
  double checked(double d, const std::string& path) const {
    if (!std::isfinite(d)) fail(path, "must be finite");
    if (!std::isfinite(float(d))) fail(path, "is out of the float range (|value| > 3.4e38)");
    return d;
  }

  double number(const json& j, const char* key, const std::string& path, double def) const {
    if (!j.contains(key)) return def;
    const json& v = j.at(key);
    if (!v.is_number()) fail(path + "." + key, std::string("expected a number, got ") + v.type_name());
    return checked(v.get<double>(), path + "." + key);
  }

  std::string string(const json& j, const char* key, const std::string& path, const char* def = nullptr) const {
    if (!j.contains(key)) {
      if (def) return def;
      fail(path + "." + key, "missing");
    }
    const json& v = j.at(key);
    if (!v.is_string()) fail(path + "." + key, std::string("expected a string, got ") + v.type_name());
    return v.get<std::string>();
  }

  // One of the names in `names` (an enum's table, core/enum_names.h), else `def`; other strings are errors.
  template <class E, size_t N>
  E choice(const json& j, const char* key, const std::string& path, E def, const std::string_view (&names)[N]) const {
    if (!j.contains(key)) return def;
    const std::string v = string(j, key, path);
    if (const std::optional<E> e = enum_from_name<E>(v, names)) return *e;
    fail(path + "." + key, "'" + v + "' is not one of: " + join(enum_names(names)));
  }

  std::vector<double> numbers(const json& v, const std::string& path, size_t n) const {
    if (!v.is_array() || v.size() != n) fail(path, "expected an array of " + std::to_string(n) + " numbers");
    std::vector<double> out;
    for (size_t i = 0; i < n; ++i) {
      if (!v[i].is_number()) fail(path + "[" + std::to_string(i) + "]", "expected a number");
      out.push_back(checked(v[i].get<double>(), path + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  Vec3 vec3(const json& j, const char* key, const std::string& path, const Vec3& def) const {
    return Vec3(dvec3(j, key, path, glm::dvec3(def)));
  }

  glm::dvec3 dvec3(const json& j, const char* key, const std::string& path, const glm::dvec3& def) const {
    if (!j.contains(key)) return def;
    const auto v = numbers(j.at(key), path + "." + key, 3);
    return glm::dvec3(v[0], v[1], v[2]);
  }

  // An RGB value that must not be negative.
  Vec3 colour(const json& j, const char* key, const std::string& path, const Vec3& def) const {
    const Vec3 c = vec3(j, key, path, def);
    if (c.x < 0.f || c.y < 0.f || c.z < 0.f) fail(path + "." + key, "must not be negative");
    return c;
  }

  // A 4x4 matrix as 4 rows of 4 numbers or 16 numbers, row-major.
  glm::dmat4 matrix(const json& v, const std::string& path) const {
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
};

std::string read_file(const fs::path& p, const std::string& what) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw SceneError(what + ": cannot open " + p.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw SceneError(what + ": read error on " + p.string());
  return ss.str();
}

struct ObjMesh {
  std::vector<Triangle> tris;
  std::vector<TriangleShading> shading;  // one per triangle when the OBJ has normals or uvs
  std::vector<bool> flip;
  bool has_shading = false;
};

// Vertices are transformed by xf, translated and re-expressed in the camera frame in double precision (see
// core/camera_frame.h), then rounded once to float.
ObjMesh load_obj(const fs::path& file, const std::string& label, const glm::dmat4& xf, const glm::dvec3& translate,
                 const CameraFrame& frame, Ctx& ctx, const std::string& path) {
  const std::string text = read_file(file, ctx.name + ": " + path);
  // OBJ is text; tinyobjloader skips lines it does not know, so a binary file (an EXR named .obj, say) would load
  // as an empty mesh with only a warning.
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    ctx.fail(path, label + ": not a valid OBJ: binary data (a NUL byte at offset " + std::to_string(nul) + ")");
  tinyobj::ObjReaderConfig cfg;
  cfg.triangulate = true;
  cfg.vertex_color = false;
  tinyobj::ObjReader reader;
  // Parsed from memory with an empty material library: an OBJ's mtllib can never make us read other files.
  if (!reader.ParseFromString(text, "", cfg)) ctx.fail(path, label + ": not a valid OBJ: " + reader.Error());
  const auto& attrib = reader.GetAttrib();
  const size_t nv = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3, nt = attrib.texcoords.size() / 2;
  const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(glm::mat4(xf))));
  ObjMesh m;
  size_t degenerate = 0, face_no = 0;
  for (const auto& shape : reader.GetShapes()) {
    const auto& idx = shape.mesh.indices;
    if (idx.size() % 3 != 0) ctx.fail(path, label + ": face data is not triangulated");
    for (size_t f = 0; f + 2 < idx.size(); f += 3, ++face_no) {
      Vec3 p[3], n[3];
      Vec2 uv[3];
      bool has_n = true, has_uv = true;
      for (int k = 0; k < 3; ++k) {
        const auto& ix = idx[f + size_t(k)];
        if (ix.vertex_index < 0 || size_t(ix.vertex_index) >= nv)
          ctx.fail(path, label + ": triangle " + std::to_string(face_no + 1) + " refers to vertex " +
                             std::to_string(ix.vertex_index + 1) + " but the file has " + std::to_string(nv));
        const float* v = &attrib.vertices[3 * size_t(ix.vertex_index)];
        const glm::dvec4 w = xf * glm::dvec4(v[0], v[1], v[2], 1.0);
        p[k] = frame.local(glm::dvec3(w) / (w.w != 0.0 ? w.w : 1.0) + translate);
        if (!is_finite(p[k])) ctx.fail(path, label + ": vertex " + std::to_string(ix.vertex_index + 1) + " is not finite");
        if (ix.normal_index >= 0) {
          if (size_t(ix.normal_index) >= nn) ctx.fail(path, label + ": triangle " + std::to_string(face_no + 1) + " refers to normal " + std::to_string(ix.normal_index + 1) + " but the file has " + std::to_string(nn));
          const float* q = &attrib.normals[3 * size_t(ix.normal_index)];
          n[k] = nxf * Vec3(q[0], q[1], q[2]);
        } else {
          has_n = false;
        }
        if (ix.texcoord_index >= 0) {
          if (size_t(ix.texcoord_index) >= nt) ctx.fail(path, label + ": triangle " + std::to_string(face_no + 1) + " refers to texture coordinate " + std::to_string(ix.texcoord_index + 1) + " but the file has " + std::to_string(nt));
          const float* q = &attrib.texcoords[2 * size_t(ix.texcoord_index)];
          uv[k] = Vec2(q[0], q[1]);
        } else {
          has_uv = false;
        }
      }
      const Triangle tri{p[0], p[1], p[2]};
      if (is_degenerate(tri)) {
        ++degenerate;
        continue;
      }
      const Vec3 geo = glm::cross(p[1] - p[0], p[2] - p[0]);
      bool flip = false;
      TriangleShading sh;
      if (has_n) {
        const Vec3 avg = n[0] + n[1] + n[2];
        flip = glm::dot(avg, geo) < 0.f;
        // Flat-shaded faces (all normals equal) gain nothing from interpolation; keep the geometric normal.
        sh.has_normals = !(n[0] == n[1] && n[1] == n[2]);
        for (int k = 0; k < 3; ++k) sh.n[size_t(k)] = length_squared(n[k]) > 0.f ? glm::normalize(n[k]) : n[k];
      }
      if (has_uv)
        for (int k = 0; k < 3; ++k) sh.uv[size_t(k)] = uv[k];
      m.tris.push_back(tri);
      m.flip.push_back(flip);
      m.shading.push_back(sh);
      m.has_shading = m.has_shading || has_uv || sh.has_normals;
    }
  }
  if (degenerate > 0) ctx.warn(path, label + ": skipped " + std::to_string(degenerate) + " zero-area triangle(s)");
  if (m.tris.empty()) ctx.warn(path, label + ": no triangles with area");
  return m;
}

// Splits an emitter's triangles into rectangles (pairs forming a rectangle, sampled by solid angle) and the rest.
void build_area_light(AreaLight& light, const std::vector<Triangle>& tris, const std::vector<Vec3>& normals) {
  std::vector<bool> used(tris.size(), false);
  const bool pair_up = tris.size() <= 4096;
  for (size_t i = 0; pair_up && i < tris.size(); ++i) {
    if (used[i]) continue;
    for (size_t j = i + 1; j < tris.size() && !used[i]; ++j) {
      if (used[j] || glm::dot(normals[i], normals[j]) < 0.9999f) continue;
      const Vec3 a[3] = {tris[i].p0, tris[i].p1, tris[i].p2}, b[3] = {tris[j].p0, tris[j].p1, tris[j].p2};
      // Find the shared edge: vertex k of i not in j is the rectangle corner opposite the diagonal.
      int shared = 0, lone_i = -1, lone_j = -1;
      for (int k = 0; k < 3; ++k) {
        bool in = false;
        for (int l = 0; l < 3; ++l) in = in || a[k] == b[l];
        if (in) ++shared; else lone_i = k;
      }
      for (int l = 0; l < 3; ++l) {
        bool in = false;
        for (int k = 0; k < 3; ++k) in = in || a[k] == b[l];
        if (!in) lone_j = l;
      }
      if (shared != 2 || lone_i < 0 || lone_j < 0) continue;
      const Vec3 corner = a[lone_i];
      const Vec3 ex = a[(lone_i + 1) % 3] - corner, ey = a[(lone_i + 2) % 3] - corner;
      const Vec3 opposite = corner + ex + ey;
      const float size = std::max(glm::length(ex), glm::length(ey));
      if (glm::length(opposite - b[lone_j]) > 1e-5f * size) continue;  // not a parallelogram
      if (std::abs(glm::dot(ex, ey)) > 1e-5f * glm::length(ex) * glm::length(ey)) continue;  // not a rectangle
      light.rects.push_back({corner, ex, ey, normals[i], glm::length(glm::cross(ex, ey))});
      used[i] = used[j] = true;
    }
  }
  for (size_t i = 0; i < tris.size(); ++i)
    if (!used[i])
      light.tris.push_back({tris[i].p0, tris[i].p1, tris[i].p2, normals[i],
                            0.5f * glm::length(glm::cross(tris[i].p1 - tris[i].p0, tris[i].p2 - tris[i].p0))});
}

const std::vector<std::string> kSupportedIntegrators = {"intersection_test", "direct", "path", "bdpt"};
const std::vector<std::string> kSupportedMaterials = {"diffuse", "refraction", "glass", "roughconductor"};
const std::vector<std::string> kSupportedTextures = {"constant", "image", "checkerboard"};

}  // namespace

fs::path resolve_inside(const fs::path& base, const fs::path& root, const std::string& rel, const std::string& json_path,
                        bool allow_absolute) {
  if (rel.empty()) throw SceneError(json_path + ": empty path");
  const fs::path p(rel);
  if (p.is_absolute() && !allow_absolute)
    throw SceneError(json_path + ": absolute path '" + rel + "' (paths are relative to the scene file; pass --asset-root to allow others)");
  const fs::path full = fs::weakly_canonical(base / p);  // base / absolute = absolute
  fs::path croot = fs::weakly_canonical(root);
  if (croot.filename().empty()) croot = croot.parent_path();  // "root/" has an empty last component
  auto [r, f] = std::mismatch(croot.begin(), croot.end(), full.begin(), full.end());
  if (r != croot.end()) throw SceneError(json_path + ": '" + rel + "' leaves " + croot.string() + " (pass --asset-root to allow it)");
  return full;
}

std::vector<std::string> scene_asset_paths(const json& j) {
  std::vector<std::string> out;
  std::set<std::string> used_textures;
  if (!j.is_object()) return out;
  auto add = [&](const std::string& s) {
    if (std::find(out.begin(), out.end(), s) == out.end()) out.push_back(s);
  };
  const json* mats = j.contains("materials") && j["materials"].is_object() ? &j["materials"] : nullptr;
  if (j.contains("objects") && j["objects"].is_array())
    for (const auto& o : j["objects"]) {
      if (!o.is_object()) continue;
      if (o.contains("type") && o["type"] == "mesh" && o.contains("path") && o["path"].is_string()) add(o["path"].get<std::string>());
      if (mats && o.contains("material_name") && o["material_name"].is_string()) {
        const std::string m = o["material_name"];
        if (mats->contains(m) && (*mats)[m].is_object() && (*mats)[m].contains("texture_name") && (*mats)[m]["texture_name"].is_string())
          used_textures.insert((*mats)[m]["texture_name"].get<std::string>());
      }
    }
  if (j.contains("environment_map") && j["environment_map"].is_object() && j["environment_map"].contains("texture_name") &&
      j["environment_map"]["texture_name"].is_string())
    used_textures.insert(j["environment_map"]["texture_name"].get<std::string>());
  if (j.contains("textures") && j["textures"].is_object())
    for (const auto& name : used_textures)
      if (j["textures"].contains(name) && j["textures"][name].is_object() && j["textures"][name].contains("type") &&
          j["textures"][name]["type"] == "image" &&
          j["textures"][name].contains("path") && j["textures"][name]["path"].is_string())
        add(j["textures"][name]["path"].get<std::string>());
  return out;
}

LoadedScene load_scene_file(const fs::path& path, const LoadOptions& options) {
  std::string text;
  try {
    text = read_file(path, path.string());
  } catch (const SceneError&) {
    throw SceneError(path.string() + ": cannot read scene file");
  }
  const fs::path base = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  const fs::path root = options.asset_root ? *options.asset_root : base;
  return load_scene_text(text, path.string(), [&](const std::string& rel, const std::string& jp) {
    try {
      const fs::path p = resolve_inside(base, root, rel, jp, options.asset_root.has_value());
      if (!fs::is_regular_file(p)) throw SceneError(jp + ": file '" + rel + "' not found (looked at " + p.string() + ")");
      return p;
    } catch (const SceneError& e) {
      throw SceneError(path.string() + ": " + e.what());
    }
  }, options);
}

namespace {

LoadedScene load_checked(const json& j, const std::string& name, const AssetResolver& resolve, const LoadOptions& options);

}  // namespace

int json_nesting_depth(std::string_view text) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

LoadedScene load_scene_text(std::string_view text, const std::string& name, const AssetResolver& resolve,
                            const LoadOptions& options) {
  if (json_nesting_depth(text) > kMaxSceneJsonDepth)
    throw SceneError(name + ": invalid JSON: arrays/objects nested deeper than " + std::to_string(kMaxSceneJsonDepth) + " levels");
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {  // parse errors, and numbers beyond the double range (out_of_range)
    throw SceneError(name + ": invalid JSON: " + e.what());
  }
  return load_scene_json(j, name, resolve, options);
}

LoadedScene load_scene_json(const json& j, const std::string& name, const AssetResolver& resolve, const LoadOptions& options) {
  // Whatever goes wrong below (a JSON type mismatch we did not foresee, a filesystem or hashing error) leaves this
  // function as a SceneError that names the scene.
  try {
    return load_checked(j, name, resolve, options);
  } catch (const SceneError&) {
    throw;
  } catch (const std::exception& e) {
    throw SceneError(name + ": " + e.what());
  }
}

namespace {

LoadedScene load_checked(const json& j, const std::string& name, const AssetResolver& resolve, const LoadOptions& options) {
  LoadedScene out;
  Ctx ctx{name, options, out};
  Scene& s = out.scene;
  ctx.object(j, "(top level)");
  ctx.check_keys(j, "(top level)", {"integrator", "film", "camera", "textures", "materials", "objects", "environment_map"});
  Sha256 hash;
  hash.update(j.dump());
  const CameraFrame frame = camera_frame(j);
  s.frame_origin = frame.origin;
  BvhOptions bvh_options;

  // integrator
  {
    const json& in = j.contains("integrator") ? ctx.object(j["integrator"], "integrator") : json::object();
    const std::string type = ctx.string(in, "type", "integrator", "intersection_test");
    const bool direct = type == "intersection_test" || type == "direct";
    if (std::find(kSupportedIntegrators.begin(), kSupportedIntegrators.end(), type) == kSupportedIntegrators.end() &&
        !options.force_direct)
      ctx.fail("integrator.type", "'" + type + "' is not supported (supported: " + join(kSupportedIntegrators) +
                                      "); pass --integrator direct to render it with the direct-lighting integrator");
    if (options.force_direct || direct) {
      if (!direct) out.notes.push_back(name + ": integrator.type '" + type + "' rendered with the direct-lighting integrator");
      ctx.check_keys(in, "integrator",
                     {"type", "spp", "max_depth", "point_light_position", "point_light_flux", "light_samples",
                      "area_sampling", "env_sampling", "bvh"},
                     {"profile", "rr_threshold", "max_path_length", "nee", "mis"});
    } else {
      s.settings.integrator = IntegratorKind::kPath;
      if (type == "bdpt")
        out.notes.push_back(name + ": integrator.type 'bdpt' rendered with the unidirectional path tracer (the same "
                                   "image in expectation; there is no bidirectional tracer yet)");
      ctx.check_keys(in, "integrator",
                     {"type", "spp", "max_depth", "point_light_position", "point_light_flux", "light_samples",
                      "area_sampling", "env_sampling", "bvh", "profile", "rr_threshold"},
                     {"max_path_length", "nee", "mis"});
      const std::string profile = ctx.string(in, "profile", "integrator", "MIS");
      if (profile == "MIS" || profile == "MultipleImportanceSampling") s.settings.profile = PathProfile::kMis;
      else if (profile == "NEE" || profile == "NextEventEstimation") s.settings.profile = PathProfile::kNee;
      else if (profile == "RW" || profile == "RandomWalk") s.settings.profile = PathProfile::kRw;
      else ctx.fail("integrator.profile", "'" + profile + "' is not one of: MIS, MultipleImportanceSampling, NEE, "
                                          "NextEventEstimation, RW, RandomWalk");
      const double rr = ctx.number(in, "rr_threshold", "integrator", 0.1);
      if (!(rr >= 0)) ctx.fail("integrator.rr_threshold", "must not be negative");
      s.settings.rr_threshold = float(rr);
    }
    const double spp = ctx.number(in, "spp", "integrator", 8);
    if (!(spp >= 1 && spp <= kMaxSpp) || spp != std::floor(spp)) ctx.fail("integrator.spp", "must be an integer in [1, " + std::to_string(kMaxSpp) + "]");
    s.settings.spp = options.spp ? *options.spp : uint32_t(spp);
    const double depth = ctx.number(in, "max_depth", "integrator", 16);
    if (!(depth >= 0 && depth <= 1024) || depth != std::floor(depth)) ctx.fail("integrator.max_depth", "must be an integer in [0, 1024]");
    s.settings.max_depth = int(depth);
    const double ls = ctx.number(in, "light_samples", "integrator", 1);
    if (!(ls >= 1 && ls <= 4096) || ls != std::floor(ls)) ctx.fail("integrator.light_samples", "must be an integer in [1, 4096]");
    s.settings.light_samples = int(ls);
    s.settings.area_sampling = ctx.choice(in, "area_sampling", "integrator", AreaSampling::kAuto, kAreaSamplingNames);
    s.settings.env_sampling = ctx.choice(in, "env_sampling", "integrator", EnvSampling::kMis, kEnvSamplingNames);
    bvh_options.split = ctx.choice(in, "bvh", "integrator", SplitMethod::kSah, kSplitMethodNames);
    if (options.area_sampling) s.settings.area_sampling = *options.area_sampling;
    if (options.env_sampling) s.settings.env_sampling = *options.env_sampling;
    if (options.bvh) bvh_options.split = *options.bvh;
    PointLight pl;
    pl.position = frame.local(ctx.dvec3(in, "point_light_position", "integrator", glm::dvec3(0.0, 5.0, 0.0)));
    pl.flux = ctx.vec3(in, "point_light_flux", "integrator", Vec3(1.f));
    if (pl.flux.x < 0.f || pl.flux.y < 0.f || pl.flux.z < 0.f) ctx.fail("integrator.point_light_flux", "must not be negative");
    if (max_component(pl.flux) > 0.f) s.point_light = pl;
  }

  // film
  {
    const json& f = j.contains("film") ? ctx.object(j["film"], "film") : json::object();
    ctx.check_keys(f, "film", {"resolution", "filter"});
    if (f.contains("resolution")) {
      const auto r = ctx.numbers(f["resolution"], "film.resolution", 2);
      for (int i = 0; i < 2; ++i)
        if (!(r[size_t(i)] >= 1 && r[size_t(i)] <= kMaxResolution) || r[size_t(i)] != std::floor(r[size_t(i)]))
          ctx.fail("film.resolution[" + std::to_string(i) + "]", "must be an integer in [1, " + std::to_string(kMaxResolution) + "]");
      s.width = int(r[0]);
      s.height = int(r[1]);
      if (uint64_t(s.width) * uint64_t(s.height) > kMaxPixels) ctx.fail("film.resolution", "more than 2^28 pixels");
    }
    if (f.contains("filter")) {
      const json& fl = ctx.object(f["filter"], "film.filter");
      const std::string t = fl.is_object() && fl.contains("type") && fl["type"].is_string() ? fl["type"].get<std::string>() : "box";
      if (t != "box") out.notes.push_back(name + ": film.filter '" + t + "' rendered with a box filter");
    }
  }

  // camera
  {
    const json& c = j.contains("camera") ? ctx.object(j["camera"], "camera") : json::object();
    ctx.check_keys(c, "camera", {"position", "look_at", "ref_up", "fov", "focal_length"});
    const Vec3 pos = frame.local(ctx.dvec3(c, "position", "camera", glm::dvec3(0, 0, 1)));
    const Vec3 at = frame.local(ctx.dvec3(c, "look_at", "camera", glm::dvec3(0, 0, 0)));
    const Vec3 up = ctx.vec3(c, "ref_up", "camera", Vec3(0, 1, 0));
    const double fov = ctx.number(c, "fov", "camera", 45);
    const double fl = ctx.number(c, "focal_length", "camera", 1);
    if (!(fl > 0)) ctx.fail("camera.focal_length", "must be positive");
    try {
      s.camera = Camera::look_at(pos, at, up, float(fov));
    } catch (const std::invalid_argument& e) {
      ctx.fail("camera", e.what());
    }
  }

  // textures and materials, loaded on first use
  const json& textures = j.contains("textures") ? ctx.object(j["textures"], "textures") : json::object();
  const json& materials = j.contains("materials") ? ctx.object(j["materials"], "materials") : json::object();
  std::map<std::string, uint32_t> texture_index, material_index;
  s.materials.push_back(Material{});  // index 0: no material

  auto known_names = [](const json& o) {
    std::vector<std::string> v;
    for (auto it = o.begin(); it != o.end(); ++it) v.push_back(it.key());
    return join(v);
  };

  auto use_texture = [&](const std::string& tname, const std::string& from) -> uint32_t {
    if (auto it = texture_index.find(tname); it != texture_index.end()) return it->second;
    if (!textures.contains(tname)) ctx.fail(from, "no texture named '" + tname + "' (defined: " + known_names(textures) + ")");
    const std::string tp = "textures." + tname;
    const json& t = ctx.object(textures[tname], tp);
    const std::string type = ctx.string(t, "type", tp);
    Texture tex;
    if (type == "constant") {
      ctx.check_keys(t, tp, {"type", "color"});
      if (!t.contains("color")) ctx.fail(tp + ".color", "missing");
      tex.color = ctx.colour(t, "color", tp, Vec3(1.f));
    } else if (type == "image") {
      ctx.check_keys(t, tp, {"type", "path", "tex_coordinate_generator"});
      const std::string rel = ctx.string(t, "path", tp);
      const fs::path file = resolve(rel, tp + ".path");
      try {
        ExrImage img = read_exr(file);
        for (float v : img.pixels.rgb)
          if (!std::isfinite(v)) ctx.fail(tp + ".path", rel + ": contains non-finite pixel values");
        tex.image = std::make_shared<const Image>(std::move(img.pixels));
      } catch (const ImageError& e) {
        ctx.fail(tp + ".path", e.what());
      }
      hash.update(sha256_file(file));
      out.assets.push_back(rel);
    } else if (type == "checkerboard") {
      ctx.check_keys(t, tp, {"type", "color0", "color1", "tex_coordinate_generator"});
      tex.checkerboard = true;
      tex.color = ctx.colour(t, "color0", tp, Vec3(0.4f));
      tex.color1 = ctx.colour(t, "color1", tp, Vec3(0.2f));
    } else {
      ctx.fail(tp + ".type", "'" + type + "' is not supported (supported: " + join(kSupportedTextures) + ")");
    }
    if ((type == "image" || type == "checkerboard") && t.contains("tex_coordinate_generator")) {
      const std::string gp = tp + ".tex_coordinate_generator";
      const json& g = ctx.object(t["tex_coordinate_generator"], gp);
      ctx.check_keys(g, gp, {"type", "scale", "delta"});
      const std::string gt = ctx.string(g, "type", gp, "uvmapping2d");
      if (gt != "uvmapping2d") ctx.fail(gp + ".type", "'" + gt + "' is not supported (supported: uvmapping2d)");
      if (g.contains("scale")) { const auto v = ctx.numbers(g["scale"], gp + ".scale", 2); tex.scale = Vec2(float(v[0]), float(v[1])); }
      if (g.contains("delta")) { const auto v = ctx.numbers(g["delta"], gp + ".delta", 2); tex.delta = Vec2(float(v[0]), float(v[1])); }
    }
    s.textures.push_back(std::move(tex));
    const uint32_t idx = uint32_t(s.textures.size() - 1);
    texture_index[tname] = idx;
    return idx;
  };

  auto use_material = [&](const std::string& mname, const std::string& from) -> uint32_t {
    if (auto it = material_index.find(mname); it != material_index.end()) return it->second;
    if (!materials.contains(mname)) ctx.fail(from, "no material named '" + mname + "' (defined: " + known_names(materials) + ")");
    const std::string mp = "materials." + mname;
    const json& m = ctx.object(materials[mname], mp);
    const std::string type = ctx.string(m, "type", mp);
    Material mat;
    if (type == "diffuse") {
      ctx.check_keys(m, mp, {"type", "texture_name", "twosided"});
      mat.kind = MaterialKind::kDiffuse;
      mat.texture = use_texture(ctx.string(m, "texture_name", mp), mp + ".texture_name");
      if (m.contains("twosided")) {
        if (!m["twosided"].is_boolean()) ctx.fail(mp + ".twosided", "expected true or false");
        mat.twosided = m["twosided"].get<bool>();
      }
    } else if (type == "refraction") {
      ctx.check_keys(m, mp, {"type", "eta"});
      mat.kind = MaterialKind::kRefraction;
      mat.eta = float(ctx.number(m, "eta", mp, 1.5));
      if (!(mat.eta > 0.f)) ctx.fail(mp + ".eta", "must be positive");
    } else if (type == "glass" || type == "roughconductor") {
      if (s.settings.integrator != IntegratorKind::kPath)
        ctx.fail(mp + ".type", "'" + type + "' needs the path integrator (integrator.type path or bdpt); the direct "
                               "integrator renders only diffuse and refraction");
      if (type == "glass") {
        ctx.check_keys(m, mp, {"type", "eta", "R", "T"});
        mat.kind = MaterialKind::kGlass;
        mat.eta = float(ctx.number(m, "eta", mp, 1.5));
        if (!(mat.eta > 0.f)) ctx.fail(mp + ".eta", "must be positive");
        mat.reflect_tint = ctx.colour(m, "R", mp, Vec3(1.f));
        mat.transmit_tint = ctx.colour(m, "T", mp, Vec3(1.f));
      } else {
        ctx.check_keys(m, mp, {"type", "alpha_x", "alpha_y", "etaI", "etaT", "k", "texture_name"});
        mat.kind = MaterialKind::kRoughConductor;
        mat.alpha_x = float(ctx.number(m, "alpha_x", mp, 0.1));
        mat.alpha_y = float(ctx.number(m, "alpha_y", mp, 0.1));
        for (const char* key : {"alpha_x", "alpha_y"}) {
          const double a = ctx.number(m, key, mp, 0.1);
          if (!(a >= 1e-4 && a <= 10)) ctx.fail(mp + "." + key, "must be in [1e-4, 10]");
        }
        mat.eta_i = ctx.vec3(m, "etaI", mp, Vec3(1.f));
        if (!(mat.eta_i.x > 0.f && mat.eta_i.y > 0.f && mat.eta_i.z > 0.f)) ctx.fail(mp + ".etaI", "must be positive");
        mat.eta_t = ctx.colour(m, "etaT", mp, Vec3(1.f));
        mat.k = ctx.colour(m, "k", mp, Vec3(1.f));
        if (m.contains("texture_name")) {
          mat.texture = use_texture(ctx.string(m, "texture_name", mp), mp + ".texture_name");
        } else {
          s.textures.push_back(Texture{});  // white: the conductor's Fresnel reflectance alone
          mat.texture = uint32_t(s.textures.size() - 1);
        }
      }
    } else {
      ctx.fail(mp + ".type", "'" + type + "' is not supported (supported: " + join(kSupportedMaterials) + ")");
    }
    s.materials.push_back(mat);
    const uint32_t idx = uint32_t(s.materials.size() - 1);
    material_index[mname] = idx;
    return idx;
  };

  // objects
  if (!j.contains("objects")) ctx.fail("objects", "missing");
  const json& objects = j["objects"];
  if (!objects.is_array()) ctx.fail("objects", "expected an array");
  std::vector<uint32_t> triangle_object;  // object index of each triangle, for coincident-face warnings
  for (size_t oi = 0; oi < objects.size(); ++oi) {
    const std::string op = "objects[" + std::to_string(oi) + "]";
    const json& o = ctx.object(objects[oi], op);
    const std::string type = ctx.string(o, "type", op);
    // Light
    std::optional<Vec3> radiance;
    if (o.contains("light")) {
      const json& l = ctx.object(o["light"], op + ".light");
      ctx.check_keys(l, op + ".light", {"type", "radiance"});
      const std::string lt = ctx.string(l, "type", op + ".light", "area");
      if (lt != "area") ctx.fail(op + ".light.type", "'" + lt + "' is not supported (supported: area)");
      if (!l.contains("radiance")) ctx.fail(op + ".light.radiance", "missing");
      radiance = ctx.vec3(l, "radiance", op + ".light", Vec3(0.f));
      if (radiance->x < 0.f || radiance->y < 0.f || radiance->z < 0.f) ctx.fail(op + ".light.radiance", "must not be negative");
    }
    uint32_t mat = 0;
    if (o.contains("material_name")) mat = use_material(ctx.string(o, "material_name", op), op + ".material_name");
    else if (!radiance) ctx.fail(op + ".material_name", "missing (only emitters may omit it)");
    int32_t light_index = -1;
    if (radiance && max_component(*radiance) > 0.f) {
      s.area_lights.push_back(AreaLight{});
      s.area_lights.back().radiance = *radiance;
      light_index = int32_t(s.area_lights.size() - 1);
    } else if (radiance) {
      ctx.warn(op + ".light.radiance", "is zero; the object does not emit");
    }

    if (type == "mesh") {
      ctx.check_keys(o, op, {"type", "path", "material_name", "translate", "transform", "light"});
      const std::string rel = ctx.string(o, "path", op);
      const fs::path file = resolve(rel, op + ".path");
      const glm::dvec3 tr = ctx.dvec3(o, "translate", op, glm::dvec3(0.0));
      const glm::dmat4 xf = o.contains("transform") ? ctx.matrix(o["transform"], op + ".transform") : glm::dmat4(1.0);
      ObjMesh mesh = load_obj(file, rel, xf, tr, frame, ctx, op + ".path");
      hash.update(sha256_file(file));
      if (std::find(out.assets.begin(), out.assets.end(), rel) == out.assets.end()) out.assets.push_back(rel);
      std::vector<Vec3> normals;
      for (size_t t = 0; t < mesh.tris.size(); ++t) {
        PrimAttr a{mat, light_index, mesh.flip[t], -1};
        if (mesh.has_shading) {
          s.triangle_shading.push_back(mesh.shading[t]);
          a.shading = int32_t(s.triangle_shading.size() - 1);
        }
        s.triangles.push_back(mesh.tris[t]);
        s.triangle_attr.push_back(a);
        triangle_object.push_back(uint32_t(oi));
        const Triangle& tri = mesh.tris[t];
        Vec3 n = glm::normalize(glm::cross(tri.p1 - tri.p0, tri.p2 - tri.p0));
        normals.push_back(mesh.flip[t] ? -n : n);
      }
      if (light_index >= 0) {
        build_area_light(s.area_lights[size_t(light_index)], mesh.tris, normals);
        if (mesh.tris.empty()) ctx.warn(op + ".light", "emitter has zero area; it emits nothing");
      }
    } else if (type == "sphere") {
      ctx.check_keys(o, op, {"type", "center", "radius", "material_name", "light"});
      Sphere sp;
      sp.center = frame.local(ctx.dvec3(o, "center", op, glm::dvec3(0.0)));
      const double r = ctx.number(o, "radius", op, 1.0);
      if (r < 0) ctx.fail(op + ".radius", "must not be negative (got " + std::to_string(r) + ")");
      if (!(r > 0) || !std::isfinite(float(r))) {
        ctx.warn(op + ".radius", "is zero; the sphere is skipped");
        if (light_index >= 0) s.area_lights.pop_back();
        continue;
      }
      sp.radius = float(r);
      s.spheres.push_back(sp);
      s.sphere_attr.push_back(PrimAttr{mat, light_index, false, -1});
      if (light_index >= 0) s.area_lights[size_t(light_index)].sphere = sp;
    } else {
      ctx.fail(op + ".type", "'" + type + "' is not supported (supported: mesh, sphere)");
    }
  }
  // Textures and materials nothing uses are never loaded (their files are not even opened), but a misspelt key in
  // them still deserves a warning.
  for (auto it = materials.begin(); it != materials.end(); ++it) {
    if (material_index.count(it.key()) || !it->is_object() || !it->contains("type") || !(*it)["type"].is_string()) continue;
    const std::string type = (*it)["type"].get<std::string>(), mp = "materials." + it.key();
    if (type == "diffuse") ctx.check_keys(*it, mp, {"type", "texture_name", "twosided"});
    else if (type == "refraction") ctx.check_keys(*it, mp, {"type", "eta"});
    else if (type == "glass") ctx.check_keys(*it, mp, {"type", "eta", "R", "T"});
    else if (type == "roughconductor") ctx.check_keys(*it, mp, {"type", "alpha_x", "alpha_y", "etaI", "etaT", "k", "texture_name"});
  }
  for (auto it = textures.begin(); it != textures.end(); ++it) {
    const bool env_texture = j.contains("environment_map") && j["environment_map"].is_object() &&
                             j["environment_map"].contains("texture_name") && j["environment_map"]["texture_name"] == it.key();
    if (texture_index.count(it.key()) || env_texture || !it->is_object() || !it->contains("type") || !(*it)["type"].is_string()) continue;
    const std::string type = (*it)["type"].get<std::string>(), tp = "textures." + it.key();
    if (type == "constant") ctx.check_keys(*it, tp, {"type", "color"});
    else if (type == "image") ctx.check_keys(*it, tp, {"type", "path", "tex_coordinate_generator"});
    else if (type == "checkerboard") ctx.check_keys(*it, tp, {"type", "color0", "color1", "tex_coordinate_generator"});
  }

  // Exactly coincident triangles (z-fighting), one warning per pair of objects.
  {
    std::map<std::pair<uint32_t, uint32_t>, size_t> per_objects;
    for (const CoincidentPair& c : find_coincident_triangles(s.triangles))
      ++per_objects[{triangle_object[c.first], triangle_object[c.second]}];
    for (const auto& [objs, count] : per_objects) {
      const std::string a = "objects[" + std::to_string(objs.first) + "]", b = "objects[" + std::to_string(objs.second) + "]";
      ctx.warn(b, std::to_string(count) + " triangle(s) coincide exactly with triangles of " +
                      (objs.first == objs.second ? std::string("the same object") : a) +
                      "; which one is visible there is arbitrary (is a mesh listed twice?)");
    }
  }
  // Drop emitters that ended up without geometry (all triangles degenerate).
  for (size_t i = 0; i < s.area_lights.size(); ++i) {
    const AreaLight& l = s.area_lights[i];
    if (l.rects.empty() && l.tris.empty() && !l.sphere) {
      for (auto& a : s.triangle_attr) if (a.light == int32_t(i)) a.light = -1;
    }
  }

  // environment
  if (j.contains("environment_map")) {
    const json& e = ctx.object(j["environment_map"], "environment_map");
    ctx.check_keys(e, "environment_map", {"texture_name", "scale", "transform"});
    Environment env;
    env.texture = s.textures[use_texture(ctx.string(e, "texture_name", "environment_map"), "environment_map.texture_name")];
    if (env.texture.checkerboard) ctx.fail("environment_map.texture_name", "a checkerboard cannot be an environment map (use constant or image)");
    env.scale = float(ctx.number(e, "scale", "environment_map", 1.0));
    if (!(env.scale >= 0.f)) ctx.fail("environment_map.scale", "must not be negative");
    if (e.contains("transform")) {
      const glm::mat3 m(glm::mat4(ctx.matrix(e["transform"], "environment_map.transform")));
      const float det = glm::determinant(m);
      if (!(std::abs(det) > 1e-6f)) ctx.fail("environment_map.transform", "is singular");
      env.to_world = m;
      env.to_local = glm::inverse(m);
    }
    s.environment = std::move(env);
  }

  s.finish(bvh_options);
  s.hash = hash.hex();
  for (std::string& w : precision_warnings(s, name)) out.warnings.push_back(std::move(w));
  return out;
}

}  // namespace

}  // namespace tessera
