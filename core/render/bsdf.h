// The scattering function of a material at one surface point: evaluation, density and importance sampling of
// incident directions, for the path tracer (and the BSDF tests). Directions are world-space unit vectors pointing
// away from the surface; wo is towards the viewer, wi towards the light.
#pragma once

#include "core/render/microfacet.h"
#include "core/sampling/sampling.h"
#include "core/render/scene.h"

#include <optional>

namespace tessera {

/// A sampled incident direction. f * |cos(wi, n)| / pdf is the sample's weight; for delta lobes pdf is the lobe's
/// discrete probability and f holds the lobe's weight x pdf / |cos|.
struct BSDFSample {
  Vec3 f{0.f};        ///< BSDF value (delta lobes: see above).
  Vec3 wi{0.f};       ///< Incident direction.
  float pdf = 0.f;    ///< Solid-angle density (delta lobes: discrete probability).
  bool delta = false; ///< Sampled from a delta lobe (mirror, perfect refraction).
};

/// A material's BSDF at a point with shading normal ns and geometric normal ng (both unit, as the primitive
/// orients them; ns never points against ng).
class Bsdf {
 public:
  /// `reflectance` is the material texture's value at the point (diffuse albedo, conductor multiplier).
  Bsdf(const Material& m, const Vec3& ns, const Vec3& ng, const Vec3& reflectance);

  /// True for materials that scatter only into delta lobes (refraction, glass): f and pdf are zero everywhere.
  bool delta() const { return kind_ == MaterialKind::kRefraction || kind_ == MaterialKind::kGlass; }
  /// True when sample() uses its 1D number to choose a lobe (glass: reflection or refraction); others ignore it.
  bool lobe_choice() const { return kind_ == MaterialKind::kGlass; }
  /// True when the material scatters nothing (an emitter without a material).
  bool black() const { return kind_ == MaterialKind::kNone; }
  /// BSDF value for the pair (without the cosine).
  Vec3 f(const Vec3& wo, const Vec3& wi) const;
  /// Solid-angle density with which sample(wo, ...) returns wi (0 for delta lobes).
  float pdf(const Vec3& wo, const Vec3& wi) const;
  /// f(wo, wi), and pdf(wo, wi) in *pdf: bitwise the two calls, sharing the local directions they both compute.
  Vec3 f(const Vec3& wo, const Vec3& wi, float* pdf) const;
  /// Samples wi for wo with a 1D (lobe choice) and a 2D random number; nothing when the sample is absorbed.
  std::optional<BSDFSample> sample(const Vec3& wo, float uc, Vec2 u) const;

 private:
  // Local coordinates of w in the shading frame, z flipped so that wo's side is +z.
  Vec3 local(const Vec3& w, float side) const;
  // +1 when w lies on the side ng points to, -1 otherwise.
  float side_of(const Vec3& w) const { return glm::dot(w, ng_) > 0.f ? 1.f : -1.f; }
  // Reflection lobes scatter only between directions on the same side of the geometric surface.
  bool same_side(const Vec3& wo, const Vec3& wi) const { return glm::dot(wo, ng_) * glm::dot(wi, ng_) > 0.f; }

  MaterialKind kind_;
  Frame frame_;
  Vec3 ng_;
  Vec3 reflectance_;
  const Material* m_;
  Beckmann beckmann_;
};

}  // namespace tessera
