#include "core/geometry/triangle.h"


namespace tessera {

namespace detail {

#include "core/util/sheared_double.h"

std::optional<TriangleHit> intersect_sheared_double(const Sheared& s, float sz, float tmax) {
  const float v[9] = {s.ax, s.ay, s.az, s.bx, s.by, s.bz, s.cx, s.cy, s.cz};
  TriangleHit h;
  if (!finish_sheared_double(v, sz, tmax, &h.t, &h.b0, &h.b1, &h.b2)) return std::nullopt;
  return h;
}

}  // namespace detail

std::optional<TriangleHit> intersect_triangle(const Ray& r, const Triangle& tri) {
  if (!r.valid()) return std::nullopt;
  return intersect_triangle(WatertightRay(r), r.tmax, tri.p0, tri.p1, tri.p2);
}

}  // namespace tessera
