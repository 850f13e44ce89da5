#include "core/geometry/spawn.h"

namespace tessera {

TriangleSurface triangle_surface(const Triangle& tri) {
  TriangleSurface ts;
  // The watertight test computes a ray's distance to the triangle's plane from vertex differences (p_i - origin),
  // rounded relative to the triangle's extent, with no "t > deltaT" rejection: an origin closer to the plane than
  // that error can re-hit the triangle (or a coplanar neighbour) at t > 0. The point error alone can be zero (a
  // plane at y = 0 has exact y coordinates), so the bound also covers the extent's rounding.
  const Vec3 extent = glm::max(glm::abs(tri.p1 - tri.p0), glm::max(glm::abs(tri.p2 - tri.p0), glm::abs(tri.p2 - tri.p1)));
  ts.extent_error = gamma(12) * max_component(extent);
  const Vec3d n = glm::cross(Vec3d(tri.p1) - Vec3d(tri.p0), Vec3d(tri.p2) - Vec3d(tri.p0));
  const double len = glm::length(n);
  ts.n = len > 0.0 ? Vec3(n / len) : Vec3(0.f, 0.f, 1.f);
  return ts;
}

SurfacePoint triangle_surface_point(const Triangle& tri, const TriangleSurface& ts, float b0, float b1, float b2) {
  SurfacePoint sp;
  // Interpolated in double with the weights renormalised (b0 = 1 - b1 - b2 was rounded), so the point lies on the
  // triangle's plane up to one final rounding: the error bound stays an ulp even 1e5 units from the origin, where
  // the float expression's gamma(7) bound would push spawned rays several ulps (centimetres) off the surface.
  const double sum = double(b0) + double(b1) + double(b2);
  const double w0 = double(b0) / sum, w1 = double(b1) / sum, w2 = double(b2) / sum;
  sp.p = Vec3(w0 * Vec3d(tri.p0) + w1 * Vec3d(tri.p1) + w2 * Vec3d(tri.p2));
  sp.p_error = 2.f * kMachineEpsilon * glm::abs(sp.p);
  sp.p_error += Vec3(ts.extent_error);
  sp.n = ts.n;
  return sp;
}

SurfacePoint triangle_surface_point(const Triangle& tri, float b0, float b1, float b2) {
  return triangle_surface_point(tri, triangle_surface(tri), b0, b1, b2);
}

SurfacePoint sphere_surface_point(const Sphere& s, const Ray& r, float t) {
  const Vec3d c(s.center);
  Vec3d w = Vec3d(r.o) + double(t) * Vec3d(r.d) - c;
  double len = glm::length(w);
  if (!(len > 0.0)) { w = Vec3d(0, 0, 1); len = 1.0; }
  const Vec3d n = w / len;
  SurfacePoint sp;
  sp.p = Vec3(c + double(s.radius) * n);
  // Double-precision re-projection, then one rounding to float: bounded well inside gamma(2) of these terms.
  sp.p_error = gamma(2) * (glm::abs(sp.p) + glm::abs(s.center) + Vec3(s.radius));
  sp.n = Vec3(n);
  return sp;
}

Vec3 offset_ray_origin(const SurfacePoint& sp, const Vec3& w) {
  const float d = glm::dot(glm::abs(sp.n), sp.p_error);
  Vec3 offset = d * sp.n;
  if (glm::dot(w, sp.n) < 0.f) offset = -offset;
  Vec3 po = sp.p + offset;
  for (int i = 0; i < 3; ++i) {
    if (offset[i] > 0.f) po[i] = next_float_up(po[i]);
    else if (offset[i] < 0.f) po[i] = next_float_down(po[i]);
  }
  return po;
}

namespace {
constexpr float kShadowEnd = 1.f - 1e-4f;  // relative: scales with the segment, not with the coordinates
}

Ray spawn_ray_to(const SurfacePoint& sp, const Vec3& to) {
  const Vec3 o = offset_ray_origin(sp, to - sp.p);
  return Ray{o, to - o, kShadowEnd};
}

Ray spawn_ray_to(const SurfacePoint& from, const SurfacePoint& to) {
  const Vec3 o = offset_ray_origin(from, to.p - from.p);
  const Vec3 target = offset_ray_origin(to, o - to.p);
  return Ray{o, target - o, kShadowEnd};
}

}  // namespace tessera
