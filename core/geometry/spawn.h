// Surface points with floating-point error bounds, and ray origins offset past that error (pbrt-v4 style).
#pragma once

#include "core/util/math.h"
#include "core/geometry/ray.h"
#include "core/geometry/sphere.h"
#include "core/geometry/triangle.h"

namespace tessera {

/// A point on a surface with a per-axis bound on its rounding error and the geometric normal.
struct SurfacePoint {
  Vec3 p;        ///< Position.
  Vec3 p_error;  ///< |computed - exact| is at most this, per axis.
  Vec3 n;        ///< Unit geometric normal (orientation as the primitive defines it).
};

/// What a triangle's surface points share: its unit geometric normal and the part of the error bound that covers
/// the rounding of the ray/triangle test (gamma(12) times the triangle's extent).
struct TriangleSurface {
  Vec3 n;              ///< Unit normal of the winding (p1 - p0) x (p2 - p0), from double precision.
  float extent_error;  ///< Added to every axis of a surface point's error bound.
};

/// The shared part of triangle_surface_point, computed once per triangle (Scene keeps one per triangle).
TriangleSurface triangle_surface(const Triangle& tri);

/// The point on a triangle at barycentrics (b0, b1, b2), with the error bound gamma(7)*sum|bi*pi| plus gamma(12)
/// times the triangle's extent (the rounding of the ray/triangle test), so rays spawned from it clear its plane.
SurfacePoint triangle_surface_point(const Triangle& tri, float b0, float b1, float b2);

/// triangle_surface_point with the triangle's shared part given (bitwise the same point).
SurfacePoint triangle_surface_point(const Triangle& tri, const TriangleSurface& ts, float b0, float b1, float b2);

/// The point where ray r meets sphere s at t, re-projected onto the sphere in double precision.
SurfacePoint sphere_surface_point(const Sphere& s, const Ray& r, float t);

/// An origin for a ray leaving sp towards w: moved along the normal, to w's side, by the error bound projected
/// on the normal, then rounded one ulp further away. No fixed epsilon: the offset scales with the coordinates.
Vec3 offset_ray_origin(const SurfacePoint& sp, const Vec3& w);

/// A ray leaving sp in direction w that cannot re-hit sp's surface at sp.
inline Ray spawn_ray(const SurfacePoint& sp, const Vec3& w) { return Ray{offset_ray_origin(sp, w), w, kInfinity}; }

/// A shadow ray from sp towards a free point `to` (a point light); it ends just short of `to` (t < 1 - 1e-4,
/// relative to the segment) so only occluders strictly between the two count.
Ray spawn_ray_to(const SurfacePoint& sp, const Vec3& to);

/// A shadow ray between two surface points, both ends offset past their error bounds, so that neither
/// surface occludes the segment by rounding, whatever the coordinates' magnitude.
Ray spawn_ray_to(const SurfacePoint& from, const SurfacePoint& to);

}  // namespace tessera
