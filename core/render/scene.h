// A loaded, render-ready scene: camera, film, materials, geometry with its BVH, and lights.
#pragma once

#include "core/geometry/bvh.h"
#include "core/render/camera.h"
#include "core/render/light.h"
#include "core/geometry/spawn.h"
#include "core/render/texture.h"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

/// The materials of the course format (the last two need the path integrator).
enum class MaterialKind {
  kNone,            ///< An emitter without a material: black apart from its emission.
  kDiffuse,         ///< Lambertian, BRDF = albedo / pi.
  kRefraction,      ///< Perfect refraction by Snell's law, total internal reflection turns into reflection.
  kGlass,           ///< Smooth dielectric: Fresnel split between mirror reflection and refraction.
  kRoughConductor,  ///< Anisotropic Beckmann microfacet metal with per-channel conductor Fresnel.
};

/// A material instance.
struct Material {
  MaterialKind kind = MaterialKind::kNone;  ///< Kind.
  uint32_t texture = 0;                     ///< Albedo (diffuse) or reflectance multiplier (roughconductor) texture.
  bool twosided = false;                    ///< Diffuse reflects on both sides (otherwise only the normal's side).
  float eta = 1.5f;                         ///< Inside / outside index of refraction (refraction, glass).
  Vec3 reflect_tint{1.f};                   ///< Glass: R, tints reflection.
  Vec3 transmit_tint{1.f};                  ///< Glass: T, tints transmission.
  float alpha_x = 0.1f, alpha_y = 0.1f;     ///< Roughconductor: Beckmann roughness along tangent and bitangent.
  Vec3 eta_i{1.f};                          ///< Roughconductor: index of refraction outside (per channel).
  Vec3 eta_t{1.f};                          ///< Roughconductor: the metal's index eta (per channel).
  Vec3 k{1.f};                              ///< Roughconductor: the metal's absorption k (per channel).
};

/// Which integrator renders the scene.
enum class IntegratorKind {
  kDirect,  ///< intersection_test: refraction chains, then direct light at the first diffuse surface.
  kPath,    ///< Unidirectional path tracing (path, and bdpt rendered with it).
};

/// How the path tracer gathers light.
enum class PathProfile {
  kMis,  ///< Light sampling and BSDF sampling combined by the power heuristic.
  kNee,  ///< Light sampling only (emitters hit by BSDF rays count only after delta bounces and camera rays).
  kRw,   ///< BSDF sampling only (a random walk; the point light, a delta light, is still sampled).
};

/// Names of the PathProfile values (scene key integrator.profile; synonyms in the loader), in declaration order.
inline constexpr std::string_view kPathProfileNames[] = {"MIS", "NEE", "RW"};

/// Per-primitive shading data.
struct PrimAttr {
  uint32_t material = 0;  ///< Material index.
  int32_t light = -1;     ///< Area light index, -1 when not emitting.
  bool flip = false;      ///< The authored normals point against the triangle's winding normal.
  int32_t shading = -1;   ///< Index into triangle_shading (triangles with normals or uvs), -1 if none.
};

/// Vertex normals and uvs of one triangle.
struct TriangleShading {
  std::array<Vec3, 3> n{};  ///< Vertex normals (zero when absent).
  std::array<Vec2, 3> uv{};  ///< Texture coordinates (zero when absent).
  bool has_normals = false;  ///< n is valid.
};

/// Integrator settings from the scene file (and overrides).
struct IntegratorSettings {
  uint32_t spp = 8;                   ///< Samples per pixel.
  int max_depth = 16;                 ///< Maximum bounces (the direct integrator counts specular ones only).
  int light_samples = 1;              ///< Area-light samples per camera sample.
  AreaSampling area_sampling = AreaSampling::kAuto;  ///< Area light strategy.
  EnvSampling env_sampling = EnvSampling::kMis;           ///< Environment strategy.
  /// Direct integrator: the first area-light draw of a camera sample is stratified jointly with its pixel position
  /// (PixelSampler::next_2d_paired); path tracer: every vertex's light draws with the previous 2D draw (the pixel
  /// position, then the BSDF direction that led to the vertex). False draws them independently (a baseline for
  /// bench/speed_vs_error).
  bool pair_light_with_pixel = true;
  IntegratorKind integrator = IntegratorKind::kDirect;    ///< Integrator.
  PathProfile profile = PathProfile::kMis;                ///< Path tracer: light gathering.
  float rr_threshold = 0.1f;  ///< Path tracer: Russian roulette once the throughput's largest channel is below this.
};

/// Everything the integrator needs to know about a surface point it hit.
struct SurfaceHit {
  SurfacePoint sp;      ///< Position, error bound and geometric normal (oriented as the primitive defines).
  Vec3 ns;              ///< Shading normal (interpolated vertex normals, or the geometric normal).
  Vec2 uv;              ///< Texture coordinates.
  const Material* material;  ///< Material.
  int32_t light;        ///< Area light index or -1.
};

/// A render-ready scene.
struct Scene {
  int width = 600, height = 600;          ///< Film resolution.
  Camera camera;                           ///< Camera.
  IntegratorSettings settings;             ///< Integrator settings.
  std::vector<Texture> textures;           ///< Textures in use.
  std::vector<Material> materials;         ///< Materials in use (index 0 is kNone).
  /// Per material: its name in the scene file's `materials` ("" for index 0). Materials are numbered in the order
  /// objects first name them.
  std::vector<std::string> material_names;
  /// Per entry of the scene file's `objects`: its `name`, or "objects[I]" when it has none.
  std::vector<std::string> object_names;
  /// Where the scene's coordinates have their origin, in the scene file's coordinates: the loader centres them on
  /// the camera (core/render/camera_frame.h), so the camera sits at (0, 0, 0).
  glm::dvec3 frame_origin{0.0};
  std::vector<Triangle> triangles;         ///< Triangles, in the scene's (camera-centred) coordinates.
  std::vector<TriangleSurface> triangle_surfaces;  ///< Per triangle: normal and error term of its points (finish()).
  std::vector<PrimAttr> triangle_attr;     ///< Per triangle.
  std::vector<TriangleShading> triangle_shading;  ///< Shading data of triangles that have some.
  std::vector<uint32_t> triangle_object;   ///< Per triangle: the index of its object in object_names.
  std::vector<Sphere> spheres;             ///< Spheres.
  std::vector<PrimAttr> sphere_attr;       ///< Per sphere.
  std::vector<uint32_t> sphere_object;     ///< Per sphere: the index of its object in object_names.
  Bvh bvh;                                 ///< Acceleration structure over triangles and spheres.
  std::optional<PointLight> point_light;   ///< The integrator's point light (absent when its flux is zero).
  std::vector<AreaLight> area_lights;      ///< Emitting objects.
  std::optional<Environment> environment;  ///< Environment map.
  std::string hash;                        ///< Content hash of the scene file and every asset it uses.

  /// Builds the BVH (with `bvh_options`) and finalises light distributions; call once geometry and lights are in.
  void finish(const BvhOptions& bvh_options = {});
  /// Shading information at a BVH hit of ray r.
  SurfaceHit surface(const Ray& r, const Hit& h) const;
};

}  // namespace tessera
