// Ray/sphere intersection with a cancellation-free quadratic.
#pragma once

#include "core/util/math.h"
#include "core/geometry/ray.h"

#include <optional>

namespace tessera {

/// A sphere given by centre and radius.
struct Sphere {
  Vec3 center{0.f};    ///< Centre.
  float radius = 1.f;  ///< Radius (> 0 for a sphere that can be hit).
};

/// Nearest t in (0, tmax) where r meets the sphere; tangent rays hit. Solved in double precision with the
/// discriminant written as a(R - |l|)(R + |l|), l being the closest-approach vector, so neither distant nor
/// huge spheres lose the root to cancellation. Invalid rays and non-positive or non-finite radii never hit.
std::optional<float> intersect_sphere(const Sphere& s, const Ray& r, float tmax);

}  // namespace tessera
