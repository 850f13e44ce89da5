// Axis-aligned boxes and the robust ray/box slab test used by BVH traversal.
#pragma once

#include "core/util/math.h"
#include "core/geometry/ray.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace tessera {

/// A closed axis-aligned box; the default box is empty (lo = +inf, hi = -inf).
struct Bounds3 {
  Vec3 lo{kInfinity};   ///< Minimum corner.
  Vec3 hi{-kInfinity};  ///< Maximum corner.

  /// Grows the box to contain p.
  void extend(const Vec3& p) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
  /// Grows the box to contain b.
  void extend(const Bounds3& b) { lo = glm::min(lo, b.lo); hi = glm::max(hi, b.hi); }
  /// True when the box contains no point.
  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  /// Centre of the box.
  Vec3 centroid() const { return 0.5f * (lo + hi); }
  /// Edge lengths (zero for an empty box).
  Vec3 diagonal() const { return empty() ? Vec3(0.f) : hi - lo; }
  /// Surface area (zero for an empty box).
  float surface_area() const {
    const Vec3 d = diagonal();
    return 2.f * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
  /// Axis of the longest edge.
  int max_extent() const {
    const Vec3 d = diagonal();
    return (d.x >= d.y && d.x >= d.z) ? 0 : (d.y >= d.z ? 1 : 2);
  }
  /// Closed containment test.
  bool contains(const Vec3& p) const {
    return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
  }
};

/// The part of a ray's extent that lies inside a box.
struct BoxInterval {
  float t0;  ///< Entry parameter (clamped to 0).
  float t1;  ///< Exit parameter (clamped to tmax, widened by the conservative rounding factor).
};

/// Per-ray constants of the slab test: reciprocal direction (inf for zero components) and its signs.
struct BoxRay {
  Vec3 o;      ///< Ray origin.
  Vec3 inv_d;  ///< 1/d per component; +-inf where d is +-0 or too small to invert.
  bool neg[3];  ///< Sign bit of inv_d per axis: the near slab plane is hi where set, lo otherwise.

  /// Precomputes the reciprocal direction of r.
  explicit BoxRay(const Ray& r)
      : o(r.o),
        inv_d(1.f / r.d.x, 1.f / r.d.y, 1.f / r.d.z),
        neg{std::signbit(inv_d.x), std::signbit(inv_d.y), std::signbit(inv_d.z)} {}
};

/// Slab test for the BVH hot path. Near and far planes are chosen by the direction's sign, never by comparing
/// distances, so a NaN distance (only 0*inf: a ray parallel to a slab with its origin exactly on that slab's
/// plane) lands where it belongs and, by the ordering of the comparisons below, does not constrain the
/// interval: the right answer for a closed box. The far distance is scaled by 1 + 2*gamma(3) so that rounding
/// never culls a box the ray touches.
inline bool slab_test(const Bounds3& b, const BoxRay& r, float tmax, float* t_entry) {
  float t0 = 0.f, t1 = tmax;
  for (int a = 0; a < 3; ++a) {
    const float near_plane = r.neg[a] ? b.hi[a] : b.lo[a];
    const float far_plane = r.neg[a] ? b.lo[a] : b.hi[a];
    const float tn = (near_plane - r.o[a]) * r.inv_d[a];
    float tf = (far_plane - r.o[a]) * r.inv_d[a];
    tf *= 1.f + 2.f * gamma(3);
    t0 = tn > t0 ? tn : t0;  // NaN tn leaves t0 unchanged
    t1 = tf < t1 ? tf : t1;  // NaN tf leaves t1 unchanged
  }
  *t_entry = t0;
  return t0 <= t1;
}

/// Robust ray/box intersection for general use: validates the ray, treats zero direction components
/// explicitly (inside the slab or not), and returns the clamped entry/exit interval or nothing.
std::optional<BoxInterval> intersect_box(const Bounds3& b, const Ray& r);

}  // namespace tessera
