// The anisotropic Beckmann microfacet distribution in a local frame (z = the surface normal, x = tangent,
// y = bitangent): normal distribution D, Smith masking (exact Beckmann Lambda, height-correlated G), and
// sampling of microfacet normals proportionally to D(m) cos(theta_m).
#pragma once

#include "core/util/math.h"

namespace tessera {

/// Beckmann distribution with roughness alpha_x (along x) and alpha_y (along y).
struct Beckmann {
  float alpha_x = 0.1f, alpha_y = 0.1f;

  /// Microfacet normal density D(m) (per solid angle, projected area normalised: integral of D cos = 1).
  float D(const Vec3& m) const;
  /// Smith's Lambda for direction w (Beckmann's exact form with erf).
  float lambda(const Vec3& w) const;
  /// Masking of direction w alone: 1 / (1 + Lambda(w)).
  float G1(const Vec3& w) const { return 1.f / (1.f + lambda(w)); }
  /// Height-correlated masking-shadowing of the pair: 1 / (1 + Lambda(wo) + Lambda(wi)).
  float G(const Vec3& wo, const Vec3& wi) const { return 1.f / (1.f + lambda(wo) + lambda(wi)); }
  /// A microfacet normal (z > 0) with density D(m) cos(theta_m) per solid angle.
  Vec3 sample_m(Vec2 u) const;
  /// Density of sample_m: D(m) cos(theta_m).
  float pdf_m(const Vec3& m) const { return m.z > 0.f ? D(m) * m.z : 0.f; }
};

}  // namespace tessera
