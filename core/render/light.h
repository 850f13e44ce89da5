// Light sources: the integrator's point light, area emitters (rectangles, triangle sets, spheres) and the
// environment map, each able to produce direct-lighting samples at a shading point.
#pragma once

#include "core/util/math.h"
#include "core/sampling/sampling.h"
#include "core/geometry/sphere.h"
#include "core/render/light_sampling.h"
#include "core/render/texture.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

namespace tessera {

/// A point light emitting `flux` (radiant power, RGB) equally in all directions: intensity = flux / (4 pi).
struct PointLight {
  Vec3 position{0.f, 5.f, 0.f};  ///< Position.
  Vec3 flux{1.f};                ///< Radiant flux.
};

/// With AreaSampling::kAuto a rectangle is sampled by solid angle when its area exceeds this times the squared
/// distance to its centre (the point is closer than about the light's width), by area otherwise. Far away the two
/// have nearly equal variance and area sampling is ~40% cheaper; close up area sampling's 1/d^2 spikes dominate
/// (docs/speed-vs-error.md, "Area light").
inline constexpr float kAutoSolidAngleRatio = 1.f;

/// With AreaSampling::kAuto and a receiver normal, a rectangle is sampled by projected solid angle when its area
/// exceeds this times the squared distance to its centre (the point is closer than about 2.2 times the light's
/// width), otherwise by area warped by its corners' unoccluded contributions (cos at the receiver x cos at the light
/// / distance^2), which costs no trigonometry. The warped area's variance is 10-20 times projected solid angle's at
/// any distance (the contribution's 1/d^4 peaks between the corners), but beyond this distance both are below 1e-3
/// relative, under the noise of anything that shadows the light (measured in core/render/light_test.cpp and
/// docs/speed-vs-error.md, "Area light").
inline constexpr float kAutoProjectedRatio = 0.2f;

/// Floor of the warps' corner weights, relative to the largest: keeps the density positive over the whole rectangle,
/// so that no point where the integrand is positive is missed (and the weight of a sample stays bounded).
inline constexpr float kBilinearWeightFloor = 0.01f;

/// A light sample as seen from a shading point.
struct LightSample {
  Vec3 p;         ///< Point on the light (for area lights) or the light position.
  Vec3 n;         ///< Light surface normal at p (zero for point lights).
  Vec3 radiance;  ///< Emitted radiance towards the shading point (0 if it faces away).
  float pdf;      ///< Density with respect to solid angle at the shading point (0: no sample).
  Vec3 p_error{0.f};  ///< Per-axis bound on the distance from p to the light's exact surface (area lights).
};

/// An emitting object: radiance `radiance` leaves the side its normal faces. Its shape is a set of rectangles
/// (sampled by solid angle), a set of other triangles (sampled by area), or a sphere.
struct AreaLight {
  /// A rectangle: corner + s*ex + t*ey, s,t in [0,1]; normal n = the emitting side.
  struct Rect {
    Vec3 corner, ex, ey, n;
    float area;
  };
  /// A triangle with its emitting normal.
  struct Tri {
    Vec3 p0, p1, p2, n;
    float area;
  };
  Vec3 radiance{0.f};            ///< Emitted radiance.
  std::vector<Rect> rects;       ///< Rectangular parts.
  std::vector<Tri> tris;         ///< Remaining triangles.
  Distribution1D part_by_area;   ///< Chooses a part (rects first, then tris) proportionally to area.
  std::optional<Sphere> sphere;  ///< Set for a spherical emitter (then rects and tris are empty).
  float total_area = 0.f;        ///< Sum of areas.

  /// Finalises the part distribution; call after filling rects/tris/sphere.
  void finish();
  /// One direct-lighting sample towards point p (u_part selects the part, u the point).
  LightSample sample(const Vec3& p, float u_part, Vec2 u, AreaSampling mode) const;
  /// One direct-lighting sample towards point p whose surface receives light on the side of the unit normal n: as
  /// sample(p, u_part, u, mode), except that AreaSampling::kAuto samples rectangles in proportion to (approximately)
  /// their unoccluded contribution at p (see kAuto). pdf() does not describe these samples.
  LightSample sample(const Vec3& p, const Vec3& n, float u_part, Vec2 u, AreaSampling mode) const;
  /// Solid-angle density with which sample(p, n, ..., mode) returns the point q (normal nq) of this light.
  float pdf(const Vec3& p, const Vec3& n, const Vec3& q, const Vec3& nq, AreaSampling mode) const;
  /// Number of parts (rectangles and triangles) among which u_part chooses; 0 for a sphere.
  int parts() const { return int(rects.size() + tris.size()); }
  /// Solid-angle density with which sample(p, ..., mode) returns the point q (normal nq) of this light: what
  /// multiple importance sampling needs when a BSDF-sampled ray from p hits the light at q.
  float pdf(const Vec3& p, const Vec3& q, const Vec3& nq, AreaSampling mode) const;

 private:
  // Whether sample() draws from rectangle rc by solid angle (else by area) for a shading point p.
  static bool by_solid_angle(const Rect& rc, const Vec3& p, AreaSampling mode);
  // Whether sample(p, n, ...) in kAuto mode draws from rectangle rc by projected solid angle (else by warped area).
  static bool projected_near(const Rect& rc, const Vec3& p);
  // Both sample()s and both pdf()s; n is null without a receiver normal.
  LightSample sample(const Vec3& p, const Vec3* n, float u_part, Vec2 u, AreaSampling mode) const;
  float pdf(const Vec3& p, const Vec3* n, const Vec3& q, const Vec3& nq, AreaSampling mode) const;
};

}  // namespace tessera

namespace tessera {

/// The environment: an equirectangular map (or a constant) around the scene, +y the pole. A direction d is
/// looked up at u = phi/(2 pi), v = theta/pi with theta = acos(d.y), phi = atan2(d.x, -d.z) in [0, 2 pi);
/// v = 0 is the image's top row. `to_local` rotates world directions into the map's frame first.
struct Environment {
  Texture texture;            ///< Constant or image texture.
  float scale = 1.f;          ///< Radiance multiplier.
  glm::mat3 to_local{1.f};    ///< World-to-map rotation (inverse of the scene's transform).
  glm::mat3 to_world{1.f};    ///< Map-to-world rotation.
  /// Bounds of luminance x sin(theta) over the map's cells (image maps only): a function of the map's pixels alone,
  /// so scenes built from the same pixels may share it (a worker keeps it for later jobs with the same map).
  std::shared_ptr<const Distribution2D> dist;
  /// Build `dist` from each raw pixel's luminance (the seed behaviour, whose support misses the bilinear lookup's:
  /// kept only so benchmarks can show the difference). Default: the bilinear neighbourhood's maximum.
  bool raw_pixel_distribution = false;

  /// Builds the importance distribution unless `dist` is set already (no-op for constant maps): the weight of the cell
  /// of pixel (x, y) is the largest luminance in its 3x3 neighbourhood (everything a bilinear lookup inside the cell
  /// can blend) times the largest sin(theta) of its row, so the pdf is positive wherever radiance() is and
  /// radiance/pdf stays bounded.
  void finish();
  /// True when the map is a constant colour (no importance sampling needed).
  bool constant() const { return texture.image == nullptr; }
  /// Radiance arriving from direction d (unit, world space).
  Vec3 radiance(const Vec3& d) const;
  /// Samples a direction by the map's importance; returns direction, radiance and solid-angle pdf.
  LightSample sample(Vec2 u) const;
  /// Solid-angle density of sample() for direction d.
  float pdf(const Vec3& d) const;
  /// radiance(d), and pdf(d) in *pdf, bitwise as the two calls but with one lookup of d's map coordinates.
  Vec3 radiance_and_pdf(const Vec3& d, float* pdf) const;
};

/// Luminance of linear Rec.709 RGB.
inline float luminance(const Vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

}  // namespace tessera
