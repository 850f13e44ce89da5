// A ray with a parametric extent: points o + t*d for t in (0, tmax).
#pragma once

#include "core/util/math.h"

namespace tessera {

/// A ray; the direction need not be normalised, distances t are in units of |d|.
struct Ray {
  Vec3 o{0.f};         ///< Origin.
  Vec3 d{0.f, 0.f, 1.f};  ///< Direction.
  float tmax = kInfinity;  ///< Far end of the ray's extent.

  /// Point at parameter t.
  Vec3 at(float t) const { return o + t * d; }

  /// True when origin and direction are finite, the direction is non-zero and tmax is not NaN.
  bool valid() const {
    return is_finite(o) && is_finite(d) && (d.x != 0.f || d.y != 0.f || d.z != 0.f) && !std::isnan(tmax);
  }
};

}  // namespace tessera
