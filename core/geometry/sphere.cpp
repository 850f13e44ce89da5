#include "core/geometry/sphere.h"

#include <cmath>

namespace tessera {

std::optional<float> intersect_sphere(const Sphere& s, const Ray& r, float tmax) {
  if (!(s.radius > 0.f) || !std::isfinite(s.radius) || !is_finite(s.center)) return std::nullopt;
  const Vec3d f = Vec3d(r.o) - Vec3d(s.center);
  const Vec3d d = Vec3d(r.d);
  const double a = glm::dot(d, d);
  if (!(a > 0.0) || !std::isfinite(a)) return std::nullopt;
  const double h = glm::dot(f, d);  // half of the linear coefficient
  const Vec3d l = f - (h / a) * d;  // from the centre to the ray's closest approach
  const double R = s.radius;
  const double ll = glm::length(l);
  const double disc = (R - ll) * (R + ll);  // = (h^2 - a*c) / a without the cancellation
  if (!(disc >= 0.0)) return std::nullopt;
  const double c = glm::dot(f, f) - R * R;
  const double q = -(h + std::copysign(std::sqrt(a * disc), h));
  double t0 = q / a;
  double t1 = (q != 0.0) ? c / q : t0;
  if (t0 > t1) std::swap(t0, t1);
  for (double t : {t0, t1}) {
    const float tf = float(t);
    if (tf > 0.f && tf < tmax) return tf;
  }
  return std::nullopt;
}

}  // namespace tessera
