// The scene loader in four stages: parse (checked reads of the JSON, core/scene/scene_json.h), resolve assets (OBJ meshes,
// core/scene/obj_mesh.h, and EXR textures, read as the objects that use them are parsed), validate (core/scene/scene_validate.h)
// and build (core/scene/scene_build.h). A scene's hash covers its JSON and every asset it reads, in the order they are read.
#include "core/scene/scene_loader.h"

#include "core/render/camera_frame.h"
#include "core/scene/checked_files.h"
#include "core/util/enum_names.h"
#include "core/util/file_io.h"
#include "core/image/image.h"
#include "core/scene/obj_mesh.h"
#include "core/scene/scene_build.h"
#include "core/scene/scene_json.h"
#include "core/scene/scene_validate.h"
#include "core/util/sha256.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <span>

namespace tessera {

using json = nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr int kMaxResolution = 65536;
constexpr uint64_t kMaxPixels = uint64_t(1) << 28;
constexpr uint32_t kMaxSpp = 1u << 20;

const std::vector<std::string> kSupportedIntegrators = {"intersection_test", "direct", "path", "bdpt"};
const std::vector<std::string> kSupportedMaterials = {"diffuse", "refraction", "glass", "roughconductor"};
const std::vector<std::string> kSupportedTextures = {"constant", "image", "checkerboard"};

// The keys each material and texture type has (unknown ones are warned about, used or not).
constexpr const char* kDiffuseKeys[] = {"type", "texture_name", "twosided"};
constexpr const char* kRefractionKeys[] = {"type", "eta"};
constexpr const char* kGlassKeys[] = {"type", "eta", "R", "T"};
constexpr const char* kRoughConductorKeys[] = {"type", "alpha_x", "alpha_y", "etaI", "etaT", "k", "texture_name"};
constexpr const char* kConstantKeys[] = {"type", "color"};
constexpr const char* kImageKeys[] = {"type", "path", "tex_coordinate_generator"};
constexpr const char* kCheckerboardKeys[] = {"type", "color0", "color1", "tex_coordinate_generator"};

struct TypeKeys {
  const char* type;
  std::span<const char* const> keys;
};
constexpr TypeKeys kMaterialKeys[] = {{"diffuse", kDiffuseKeys}, {"refraction", kRefractionKeys},
                                      {"glass", kGlassKeys}, {"roughconductor", kRoughConductorKeys}};
constexpr TypeKeys kTextureKeys[] = {{"constant", kConstantKeys}, {"image", kImageKeys},
                                     {"checkerboard", kCheckerboardKeys}};

// The keys of `type` in `table`; empty for types the table does not know.
std::span<const char* const> keys_of(std::span<const TypeKeys> table, const std::string& type) {
  for (const TypeKeys& t : table)
    if (type == t.type) return t.keys;
  return {};
}

// The names defined in a "textures" or "materials" object, for messages.
std::string known_names(const json& o) {
  std::vector<std::string> v;
  for (auto it = o.begin(); it != o.end(); ++it) v.push_back(it.key());
  return join_names(v);
}

// One load, filling `out.scene`. Sections are parsed in the format's order; textures and materials are parsed (and
// image textures read) when an object or the environment first uses them, so unused ones never open a file.
class Loader {
 public:
  Loader(const json& j, const std::string& name, const AssetResolver& resolve, const LoadOptions& options,
         LoadedScene& out)
      : j_(j), resolve_(resolve), options_(options), out_(out), s_(out.scene), ctx_{name, options, out} {}

  // Parse and resolve assets section by section, then validate the whole scene, then build it.
  void run() {
    ctx_.object(j_, "(top level)");
    ctx_.check_keys(j_, "(top level)", {"integrator", "film", "camera", "textures", "materials", "objects", "environment_map"});
    hash_.update(j_.dump());
    frame_ = camera_frame(j_);
    s_.frame_origin = frame_.origin;
    integrator();
    film();
    camera();
    textures_ = j_.contains("textures") ? &ctx_.object(j_["textures"], "textures") : &empty_;
    materials_ = j_.contains("materials") ? &ctx_.object(j_["materials"], "materials") : &empty_;
    s_.materials.push_back(Material{});  // index 0: no material
    s_.material_names.emplace_back();
    objects();
    unused_keys();
    environment();
    validate_scene(s_, ctx_);
    if (options_.build) {
      build_scene(s_, bvh_options_);
      // A table built from recorded pixels goes into the record, for the next scene with the same map.
      if (s_.environment && options_.checked_files && !env_file_.empty() && !out_.environment_reused)
        options_.checked_files->remember_environment(env_file_, s_.environment->texture.image.get(),
                                                     s_.environment->dist);
    }
    s_.hash = hash_.hex();
  }

 private:
  void integrator();
  void film();
  void camera();
  // The object `name` in "textures" or "materials" (`what` is "texture" or "material"), used at JSON path `from`.
  const json& definition(const json& table, const char* what, const std::string& name, const std::string& path,
                         const std::string& from) const;
  uint32_t texture(const std::string& name, const std::string& from);
  uint32_t material(const std::string& name, const std::string& from);
  void objects();
  void mesh(const json& o, const std::string& op, uint32_t mat, int32_t light_index, size_t oi);
  void unused_keys();
  void environment();

  const json& j_;
  const AssetResolver& resolve_;
  const LoadOptions& options_;
  LoadedScene& out_;
  Scene& s_;
  SceneJson ctx_;
  CameraFrame frame_;  // positions are re-expressed around the camera (core/render/camera_frame.h)
  Sha256 hash_;
  BvhOptions bvh_options_;
  const json empty_ = json::object();
  const json* textures_ = &empty_;
  const json* materials_ = &empty_;
  std::map<std::string, uint32_t> texture_index_, material_index_;
  // Where an image texture came from: its file and, when its pixels came from LoadOptions::checked_files, the
  // environment sampling table recorded with them.
  struct ImageSource {
    fs::path file;
    std::shared_ptr<const Distribution2D> environment;
  };
  std::map<uint32_t, ImageSource> image_source_;  // by texture index
  fs::path env_file_;                             // the environment map's file (empty: constant or none)
};

void Loader::integrator() {
  const json& in = j_.contains("integrator") ? ctx_.object(j_["integrator"], "integrator") : json::object();
  const std::string type = ctx_.string(in, "type", "integrator", "intersection_test");
  const bool direct = type == "intersection_test" || type == "direct";
  if (std::find(kSupportedIntegrators.begin(), kSupportedIntegrators.end(), type) == kSupportedIntegrators.end() &&
      !options_.force_direct)
    ctx_.fail("integrator.type", "'" + type + "' is not supported (supported: " + join_names(kSupportedIntegrators) +
                                    "); pass --integrator direct to render it with the direct-lighting integrator");
  if (options_.force_direct || direct) {
    if (!direct) out_.notes.push_back(ctx_.name + ": integrator.type '" + type + "' rendered with the direct-lighting integrator");
    ctx_.check_keys(in, "integrator",
                   {"type", "spp", "max_depth", "point_light_position", "point_light_flux", "light_samples",
                    "area_sampling", "env_sampling", "bvh"},
                   {"profile", "rr_threshold", "max_path_length", "nee", "mis"});
  } else {
    s_.settings.integrator = IntegratorKind::kPath;
    if (type == "bdpt")
      out_.notes.push_back(ctx_.name + ": integrator.type 'bdpt' rendered with the unidirectional path tracer (the same "
                                 "image in expectation; there is no bidirectional tracer yet)");
    ctx_.check_keys(in, "integrator",
                   {"type", "spp", "max_depth", "point_light_position", "point_light_flux", "light_samples",
                    "area_sampling", "env_sampling", "bvh", "profile", "rr_threshold"},
                   {"max_path_length", "nee", "mis"});
    const std::string profile = ctx_.string(in, "profile", "integrator", "MIS");
    if (profile == "MIS" || profile == "MultipleImportanceSampling") s_.settings.profile = PathProfile::kMis;
    else if (profile == "NEE" || profile == "NextEventEstimation") s_.settings.profile = PathProfile::kNee;
    else if (profile == "RW" || profile == "RandomWalk") s_.settings.profile = PathProfile::kRw;
    else ctx_.fail("integrator.profile", "'" + profile + "' is not one of: MIS, MultipleImportanceSampling, NEE, "
                                        "NextEventEstimation, RW, RandomWalk");
    const double rr = ctx_.number(in, "rr_threshold", "integrator", 0.1);
    if (!(rr >= 0)) ctx_.fail("integrator.rr_threshold", "must not be negative");
    s_.settings.rr_threshold = float(rr);
  }
  const double spp = ctx_.number(in, "spp", "integrator", 8);
  if (!(spp >= 1 && spp <= kMaxSpp) || spp != std::floor(spp)) ctx_.fail("integrator.spp", "must be an integer in [1, " + std::to_string(kMaxSpp) + "]");
  s_.settings.spp = options_.spp ? *options_.spp : uint32_t(spp);
  const double depth = ctx_.number(in, "max_depth", "integrator", 16);
  if (!(depth >= 0 && depth <= 1024) || depth != std::floor(depth)) ctx_.fail("integrator.max_depth", "must be an integer in [0, 1024]");
  s_.settings.max_depth = int(depth);
  const double ls = ctx_.number(in, "light_samples", "integrator", 1);
  if (!(ls >= 1 && ls <= 4096) || ls != std::floor(ls)) ctx_.fail("integrator.light_samples", "must be an integer in [1, 4096]");
  s_.settings.light_samples = int(ls);
  s_.settings.area_sampling = ctx_.choice(in, "area_sampling", "integrator", AreaSampling::kAuto, kAreaSamplingNames);
  s_.settings.env_sampling = ctx_.choice(in, "env_sampling", "integrator", EnvSampling::kMis, kEnvSamplingNames);
  bvh_options_.split = ctx_.choice(in, "bvh", "integrator", SplitMethod::kSah, kSplitMethodNames);
  if (options_.area_sampling) s_.settings.area_sampling = *options_.area_sampling;
  if (options_.env_sampling) s_.settings.env_sampling = *options_.env_sampling;
  if (options_.bvh) bvh_options_.split = *options_.bvh;
  PointLight pl;
  pl.position = frame_.local(ctx_.dvec3(in, "point_light_position", "integrator", glm::dvec3(0.0, 5.0, 0.0)));
  pl.flux = ctx_.vec3(in, "point_light_flux", "integrator", Vec3(1.f));
  if (pl.flux.x < 0.f || pl.flux.y < 0.f || pl.flux.z < 0.f) ctx_.fail("integrator.point_light_flux", "must not be negative");
  if (max_component(pl.flux) > 0.f) s_.point_light = pl;
}

void Loader::film() {
  const json& f = j_.contains("film") ? ctx_.object(j_["film"], "film") : json::object();
  ctx_.check_keys(f, "film", {"resolution", "filter"});
  if (f.contains("resolution")) {
    const auto r = ctx_.numbers(f["resolution"], "film.resolution", 2);
    for (int i = 0; i < 2; ++i)
      if (!(r[size_t(i)] >= 1 && r[size_t(i)] <= kMaxResolution) || r[size_t(i)] != std::floor(r[size_t(i)]))
        ctx_.fail("film.resolution[" + std::to_string(i) + "]", "must be an integer in [1, " + std::to_string(kMaxResolution) + "]");
    s_.width = int(r[0]);
    s_.height = int(r[1]);
    if (uint64_t(s_.width) * uint64_t(s_.height) > kMaxPixels) ctx_.fail("film.resolution", "more than 2^28 pixels");
  }
  if (f.contains("filter")) {
    const json& fl = ctx_.object(f["filter"], "film.filter");
    const std::string t = fl.is_object() && fl.contains("type") && fl["type"].is_string() ? fl["type"].get<std::string>() : "box";
    if (t != "box") out_.notes.push_back(ctx_.name + ": film.filter '" + t + "' rendered with a box filter");
  }
}

void Loader::camera() {
  const json& c = j_.contains("camera") ? ctx_.object(j_["camera"], "camera") : json::object();
  ctx_.check_keys(c, "camera", {"position", "look_at", "ref_up", "fov", "focal_length"});
  const Vec3 pos = frame_.local(ctx_.dvec3(c, "position", "camera", glm::dvec3(0, 0, 1)));
  const Vec3 at = frame_.local(ctx_.dvec3(c, "look_at", "camera", glm::dvec3(0, 0, 0)));
  const Vec3 up = ctx_.vec3(c, "ref_up", "camera", Vec3(0, 1, 0));
  const double fov = ctx_.number(c, "fov", "camera", 45);
  const double fl = ctx_.number(c, "focal_length", "camera", 1);
  if (!(fl > 0)) ctx_.fail("camera.focal_length", "must be positive");
  try {
    s_.camera = Camera::look_at(pos, at, up, float(fov));
  } catch (const std::invalid_argument& e) {
    ctx_.fail("camera", e.what());
  }
}

const json& Loader::definition(const json& table, const char* what, const std::string& name, const std::string& path,
                               const std::string& from) const {
  if (!table.contains(name)) ctx_.fail(from, std::string("no ") + what + " named '" + name + "' (defined: " + known_names(table) + ")");
  return ctx_.object(table[name], path);
}

uint32_t Loader::texture(const std::string& tname, const std::string& from) {
  if (auto it = texture_index_.find(tname); it != texture_index_.end()) return it->second;
  const std::string tp = "textures." + tname;
  const json& t = definition(*textures_, "texture", tname, tp, from);
  const std::string type = ctx_.string(t, "type", tp);
  Texture tex;
  ImageSource source;  // an image texture's file, and the sampling table recorded with its pixels
  if (type == "constant") {
    ctx_.check_keys(t, tp, keys_of(kTextureKeys, type));
    if (!t.contains("color")) ctx_.fail(tp + ".color", "missing");
    tex.color = ctx_.colour(t, "color", tp, Vec3(1.f));
  } else if (type == "image") {
    ctx_.check_keys(t, tp, keys_of(kTextureKeys, type));
    const std::string rel = ctx_.string(t, "path", tp);
    const fs::path file = resolve_(rel, tp + ".path");
    source.file = file;
    // An image an earlier load found clean is not decoded again: a check (no build) needs only its digest, a build
    // its pixels too, where the record kept them.
    CheckedFiles* const known = options_.checked_files;
    std::optional<CheckedFiles::Record> record = known ? known->find(file) : std::nullopt;
    if (record && options_.build && !record->image) record.reset();
    std::string digest;
    if (record) {
      digest = std::move(record->sha256);
      if (options_.build) {
        tex.image = std::move(record->image);
        source.environment = std::move(record->environment);  // built from these very pixels
      }
      ++out_.images_reused;
    } else {
      try {
        // Only the colour is decoded, and only once the header's size is within the asset limit.
        ExrImage img = read_exr(file, {.max_pixels = options_.asset_limits.max_pixels, .colour_only = true});
        for (float v : img.pixels.rgb)
          if (!std::isfinite(v)) ctx_.fail(tp + ".path", rel + ": contains non-finite pixel values");
        tex.image = std::make_shared<const Image>(std::move(img.pixels));
      } catch (const ExrTooLarge& e) {
        ctx_.fail(tp + ".path", rel + ": image too large: " + std::to_string(e.width) + "x" + std::to_string(e.height) +
                                    " = " + std::to_string(uint64_t(e.width) * uint64_t(e.height)) +
                                    " pixels is over the limit of " + std::to_string(e.limit) + " (--max-asset-pixels)");
      } catch (const ImageError& e) {
        ctx_.fail(tp + ".path", e.what());
      }
      digest = sha256_file(file);
      if (known) known->remember(file, digest, options_.build ? tex.image : nullptr);
    }
    hash_.update(digest);
    out_.assets.push_back(rel);
  } else if (type == "checkerboard") {
    ctx_.check_keys(t, tp, keys_of(kTextureKeys, type));
    tex.checkerboard = true;
    tex.color = ctx_.colour(t, "color0", tp, Vec3(0.4f));
    tex.color1 = ctx_.colour(t, "color1", tp, Vec3(0.2f));
  } else {
    ctx_.fail(tp + ".type", "'" + type + "' is not supported (supported: " + join_names(kSupportedTextures) + ")");
  }
  if ((type == "image" || type == "checkerboard") && t.contains("tex_coordinate_generator")) {
    const std::string gp = tp + ".tex_coordinate_generator";
    const json& g = ctx_.object(t["tex_coordinate_generator"], gp);
    ctx_.check_keys(g, gp, {"type", "scale", "delta"});
    const std::string gt = ctx_.string(g, "type", gp, "uvmapping2d");
    if (gt != "uvmapping2d") ctx_.fail(gp + ".type", "'" + gt + "' is not supported (supported: uvmapping2d)");
    if (g.contains("scale")) { const auto v = ctx_.numbers(g["scale"], gp + ".scale", 2); tex.scale = Vec2(float(v[0]), float(v[1])); }
    if (g.contains("delta")) { const auto v = ctx_.numbers(g["delta"], gp + ".delta", 2); tex.delta = Vec2(float(v[0]), float(v[1])); }
  }
  s_.textures.push_back(std::move(tex));
  const uint32_t idx = uint32_t(s_.textures.size() - 1);
  texture_index_[tname] = idx;
  if (!source.file.empty()) image_source_[idx] = std::move(source);
  return idx;
}

uint32_t Loader::material(const std::string& mname, const std::string& from) {
  if (auto it = material_index_.find(mname); it != material_index_.end()) return it->second;
  const std::string mp = "materials." + mname;
  const json& m = definition(*materials_, "material", mname, mp, from);
  const std::string type = ctx_.string(m, "type", mp);
  Material mat;
  if (type == "diffuse") {
    ctx_.check_keys(m, mp, keys_of(kMaterialKeys, type));
    mat.kind = MaterialKind::kDiffuse;
    mat.texture = texture(ctx_.string(m, "texture_name", mp), mp + ".texture_name");
    if (m.contains("twosided")) {
      if (!m["twosided"].is_boolean()) ctx_.fail(mp + ".twosided", "expected true or false");
      mat.twosided = m["twosided"].get<bool>();
    }
  } else if (type == "refraction") {
    ctx_.check_keys(m, mp, keys_of(kMaterialKeys, type));
    mat.kind = MaterialKind::kRefraction;
    mat.eta = float(ctx_.number(m, "eta", mp, 1.5));
    if (!(mat.eta > 0.f)) ctx_.fail(mp + ".eta", "must be positive");
  } else if (type == "glass" || type == "roughconductor") {
    if (s_.settings.integrator != IntegratorKind::kPath)
      ctx_.fail(mp + ".type", "'" + type + "' needs the path integrator (integrator.type path or bdpt); the direct "
                             "integrator renders only diffuse and refraction");
    if (type == "glass") {
      ctx_.check_keys(m, mp, keys_of(kMaterialKeys, type));
      mat.kind = MaterialKind::kGlass;
      mat.eta = float(ctx_.number(m, "eta", mp, 1.5));
      if (!(mat.eta > 0.f)) ctx_.fail(mp + ".eta", "must be positive");
      mat.reflect_tint = ctx_.colour(m, "R", mp, Vec3(1.f));
      mat.transmit_tint = ctx_.colour(m, "T", mp, Vec3(1.f));
    } else {
      ctx_.check_keys(m, mp, keys_of(kMaterialKeys, type));
      mat.kind = MaterialKind::kRoughConductor;
      mat.alpha_x = float(ctx_.number(m, "alpha_x", mp, 0.1));
      mat.alpha_y = float(ctx_.number(m, "alpha_y", mp, 0.1));
      for (const char* key : {"alpha_x", "alpha_y"}) {
        const double a = ctx_.number(m, key, mp, 0.1);
        if (!(a >= 1e-4 && a <= 10)) ctx_.fail(mp + "." + key, "must be in [1e-4, 10]");
      }
      mat.eta_i = ctx_.vec3(m, "etaI", mp, Vec3(1.f));
      if (!(mat.eta_i.x > 0.f && mat.eta_i.y > 0.f && mat.eta_i.z > 0.f)) ctx_.fail(mp + ".etaI", "must be positive");
      mat.eta_t = ctx_.colour(m, "etaT", mp, Vec3(1.f));
      mat.k = ctx_.colour(m, "k", mp, Vec3(1.f));
      if (m.contains("texture_name")) {
        mat.texture = texture(ctx_.string(m, "texture_name", mp), mp + ".texture_name");
      } else {
        s_.textures.push_back(Texture{});  // white: the conductor's Fresnel reflectance alone
        mat.texture = uint32_t(s_.textures.size() - 1);
      }
    }
  } else {
    ctx_.fail(mp + ".type", "'" + type + "' is not supported (supported: " + join_names(kSupportedMaterials) + ")");
  }
  s_.materials.push_back(mat);
  s_.material_names.push_back(mname);
  const uint32_t idx = uint32_t(s_.materials.size() - 1);
  material_index_[mname] = idx;
  return idx;
}

void Loader::objects() {
  if (!j_.contains("objects")) ctx_.fail("objects", "missing");
  const json& objects = j_["objects"];
  if (!objects.is_array()) ctx_.fail("objects", "expected an array");
  for (size_t oi = 0; oi < objects.size(); ++oi) {
    const std::string op = "objects[" + std::to_string(oi) + "]";
    const json& o = ctx_.object(objects[oi], op);
    const std::string type = ctx_.string(o, "type", op);
    s_.object_names.push_back(o.contains("name") ? ctx_.string(o, "name", op) : op);
    // Light
    std::optional<Vec3> radiance;
    if (o.contains("light")) {
      const json& l = ctx_.object(o["light"], op + ".light");
      ctx_.check_keys(l, op + ".light", {"type", "radiance"});
      const std::string lt = ctx_.string(l, "type", op + ".light", "area");
      if (lt != "area") ctx_.fail(op + ".light.type", "'" + lt + "' is not supported (supported: area)");
      if (!l.contains("radiance")) ctx_.fail(op + ".light.radiance", "missing");
      radiance = ctx_.vec3(l, "radiance", op + ".light", Vec3(0.f));
      if (radiance->x < 0.f || radiance->y < 0.f || radiance->z < 0.f) ctx_.fail(op + ".light.radiance", "must not be negative");
    }
    uint32_t mat = 0;
    if (o.contains("material_name")) mat = material(ctx_.string(o, "material_name", op), op + ".material_name");
    else if (!radiance) ctx_.fail(op + ".material_name", "missing (only emitters may omit it)");
    int32_t light_index = -1;
    if (radiance && max_component(*radiance) > 0.f) {
      s_.area_lights.push_back(AreaLight{});
      s_.area_lights.back().radiance = *radiance;
      light_index = int32_t(s_.area_lights.size() - 1);
    } else if (radiance) {
      ctx_.warn(op + ".light.radiance", "is zero; the object does not emit");
    }

    if (type == "mesh") {
      mesh(o, op, mat, light_index, oi);
    } else if (type == "sphere") {
      ctx_.check_keys(o, op, {"type", "name", "center", "radius", "material_name", "light"});
      Sphere sp;
      sp.center = frame_.local(ctx_.dvec3(o, "center", op, glm::dvec3(0.0)));
      const double r = ctx_.number(o, "radius", op, 1.0);
      if (r < 0) ctx_.fail(op + ".radius", "must not be negative (got " + std::to_string(r) + ")");
      if (!(r > 0) || !std::isfinite(float(r))) {
        ctx_.warn(op + ".radius", "is zero; the sphere is skipped");
        if (light_index >= 0) s_.area_lights.pop_back();
        continue;
      }
      sp.radius = float(r);
      s_.spheres.push_back(sp);
      s_.sphere_attr.push_back(PrimAttr{mat, light_index, false, -1});
      s_.sphere_object.push_back(uint32_t(oi));
      if (light_index >= 0) s_.area_lights[size_t(light_index)].sphere = sp;
    } else {
      ctx_.fail(op + ".type", "'" + type + "' is not supported (supported: mesh, sphere)");
    }
  }
}

void Loader::mesh(const json& o, const std::string& op, uint32_t mat, int32_t light_index, size_t oi) {
  ctx_.check_keys(o, op, {"type", "name", "path", "material_name", "translate", "transform", "light"});
  const std::string rel = ctx_.string(o, "path", op);
  const fs::path file = resolve_(rel, op + ".path");
  const glm::dvec3 tr = ctx_.dvec3(o, "translate", op, glm::dvec3(0.0));
  const glm::dmat4 xf = o.contains("transform") ? ctx_.matrix(o["transform"], op + ".transform") : glm::dmat4(1.0);
  ObjMesh obj = load_obj(file, rel, xf, tr, frame_, ctx_, op + ".path");
  // A file an earlier load recorded (unchanged since) is not read again for its digest.
  CheckedFiles* const known = options_.mesh_digests;
  std::optional<CheckedFiles::Record> record = known ? known->find(file) : std::nullopt;
  const std::string digest = record ? std::move(record->sha256) : sha256_file(file);
  if (known && !record) known->remember(file, digest);
  hash_.update(digest);
  if (std::find(out_.assets.begin(), out_.assets.end(), rel) == out_.assets.end()) out_.assets.push_back(rel);
  std::vector<Vec3> normals;
  for (size_t t = 0; t < obj.tris.size(); ++t) {
    PrimAttr a{mat, light_index, obj.flip[t], -1};
    if (obj.has_shading) {
      s_.triangle_shading.push_back(obj.shading[t]);
      a.shading = int32_t(s_.triangle_shading.size() - 1);
    }
    s_.triangles.push_back(obj.tris[t]);
    s_.triangle_attr.push_back(a);
    s_.triangle_object.push_back(uint32_t(oi));
    const Triangle& tri = obj.tris[t];
    Vec3 n = glm::normalize(glm::cross(tri.p1 - tri.p0, tri.p2 - tri.p0));
    normals.push_back(obj.flip[t] ? -n : n);
  }
  if (light_index >= 0) {
    build_area_light(s_.area_lights[size_t(light_index)], obj.tris, normals);
    if (obj.tris.empty()) ctx_.warn(op + ".light", "emitter has zero area; it emits nothing");
  }
}

void Loader::unused_keys() {
  // Textures and materials nothing uses are never loaded (their files are not even opened), but a misspelt key in
  // them still deserves a warning.
  for (auto it = materials_->begin(); it != materials_->end(); ++it) {
    if (material_index_.count(it.key()) || !it->is_object() || !it->contains("type") || !(*it)["type"].is_string()) continue;
    const std::span<const char* const> keys = keys_of(kMaterialKeys, (*it)["type"].get<std::string>());
    if (!keys.empty()) ctx_.check_keys(*it, "materials." + it.key(), keys);
  }
  for (auto it = textures_->begin(); it != textures_->end(); ++it) {
    const bool env_texture = j_.contains("environment_map") && j_["environment_map"].is_object() &&
                             j_["environment_map"].contains("texture_name") && j_["environment_map"]["texture_name"] == it.key();
    if (texture_index_.count(it.key()) || env_texture || !it->is_object() || !it->contains("type") || !(*it)["type"].is_string()) continue;
    const std::span<const char* const> keys = keys_of(kTextureKeys, (*it)["type"].get<std::string>());
    if (!keys.empty()) ctx_.check_keys(*it, "textures." + it.key(), keys);
  }
}

void Loader::environment() {
  if (!j_.contains("environment_map")) return;
  const json& e = ctx_.object(j_["environment_map"], "environment_map");
  ctx_.check_keys(e, "environment_map", {"texture_name", "scale", "transform"});
  Environment env;
  const uint32_t tex = texture(ctx_.string(e, "texture_name", "environment_map"), "environment_map.texture_name");
  env.texture = s_.textures[tex];
  // The sampling table depends on the map's pixels alone: one recorded with these very pixels is taken.
  if (const auto f = image_source_.find(tex); f != image_source_.end() && options_.build && options_.checked_files) {
    env_file_ = f->second.file;
    if (f->second.environment) {
      env.dist = f->second.environment;
      out_.environment_reused = true;
    }
  }
  if (env.texture.checkerboard) ctx_.fail("environment_map.texture_name", "a checkerboard cannot be an environment map (use constant or image)");
  env.scale = float(ctx_.number(e, "scale", "environment_map", 1.0));
  if (!(env.scale >= 0.f)) ctx_.fail("environment_map.scale", "must not be negative");
  if (e.contains("transform")) {
    const glm::mat3 m(glm::mat4(ctx_.matrix(e["transform"], "environment_map.transform")));
    const float det = glm::determinant(m);
    if (!(std::abs(det) > 1e-6f)) ctx_.fail("environment_map.transform", "is singular");
    env.to_world = m;
    env.to_local = glm::inverse(m);
  }
  s_.environment = std::move(env);
}

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
    text = read_file_bytes(path);
  } catch (const FileError&) {
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
    LoadedScene out;
    Loader(j, name, resolve, options, out).run();
    return out;
  } catch (const SceneError&) {
    throw;
  } catch (const std::exception& e) {
    throw SceneError(name + ": " + e.what());
  }
}

}  // namespace tessera
