#include "core/triangle.h"

#include <algorithm>

namespace tessera {

namespace detail {

std::optional<TriangleHit> intersect_sheared_double(const Sheared& s, float sz, float tmax) {
  const double e0 = double(s.bx) * s.cy - double(s.by) * s.cx;
  const double e1 = double(s.cx) * s.ay - double(s.cy) * s.ax;
  const double e2 = double(s.ax) * s.by - double(s.ay) * s.bx;
  if (std::isnan(e0) || std::isnan(e1) || std::isnan(e2)) return std::nullopt;
  if ((e0 < 0 || e1 < 0 || e2 < 0) && (e0 > 0 || e1 > 0 || e2 > 0)) return std::nullopt;
  const double det = e0 + e1 + e2;
  if (!(std::abs(det) > 0 && std::isfinite(det))) return std::nullopt;
  const double zs[3] = {double(sz) * s.az, double(sz) * s.bz, double(sz) * s.cz};
  const double inv_det = 1.0 / det;
  const double t = (e0 * zs[0] + e1 * zs[1] + e2 * zs[2]) * inv_det;
  const float tf = float(t);
  if (!(tf > 0.f && tf < tmax)) return std::nullopt;
  const TriangleHit h{tf, float(e0 * inv_det), float(e1 * inv_det), float(e2 * inv_det)};
  if (!std::isfinite(h.b0) || !std::isfinite(h.b1) || !std::isfinite(h.b2)) return std::nullopt;
  return h;
}

}  // namespace detail

std::optional<TriangleHit> intersect_triangle(const Ray& r, const Triangle& tri) {
  if (!r.valid()) return std::nullopt;
  return intersect_triangle(WatertightRay(r), r.tmax, tri.p0, tri.p1, tri.p2);
}

}  // namespace tessera
