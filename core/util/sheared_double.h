// The watertight triangle test's double-precision finish, written once for two kinds of callers: core/geometry/triangle.cpp
// (detail::intersect_sheared_double) and the BVH traversal kernels, which include this file inside their own
// namespaces (core/geometry/kernels/bvh_traverse.inl) so that each instruction set compiles its own internal copy without a call.
// No includes and no library calls (compiler builtins only), so that it can be included inside a namespace; every
// copy performs the same IEEE double operations in the same order (no contraction: -ffp-contract=off).
#pragma once

/// Finishes a watertight test in double precision, where products of floats are exact, on the sheared, permuted
/// vertices s = {ax, ay, az, bx, by, bz, cx, cy, cz}; sz is the ray's shear constant 1 / d[kz]. Returns true for a
/// hit in (0, tmax) with finite barycentrics, and writes t and the barycentrics of p0, p1, p2.
inline bool finish_sheared_double(const float (&s)[9], float sz, float tmax, float* t, float* b0, float* b1,
                                  float* b2) {
  const float ax = s[0], ay = s[1], az = s[2], bx = s[3], by = s[4], bz = s[5], cx = s[6], cy = s[7], cz = s[8];
  const double e0 = double(bx) * cy - double(by) * cx;
  const double e1 = double(cx) * ay - double(cy) * ax;
  const double e2 = double(ax) * by - double(ay) * bx;
  if (__builtin_isnan(e0) || __builtin_isnan(e1) || __builtin_isnan(e2)) return false;
  if ((e0 < 0 || e1 < 0 || e2 < 0) && (e0 > 0 || e1 > 0 || e2 > 0)) return false;
  const double det = e0 + e1 + e2;
  if (!(__builtin_fabs(det) > 0 && __builtin_isfinite(det))) return false;
  const double zs0 = double(sz) * az, zs1 = double(sz) * bz, zs2 = double(sz) * cz;
  const double inv_det = 1.0 / det;
  const double td = (e0 * zs0 + e1 * zs1 + e2 * zs2) * inv_det;
  const float tf = float(td);
  if (!(tf > 0.f && tf < tmax)) return false;
  const float w0 = float(e0 * inv_det), w1 = float(e1 * inv_det), w2 = float(e2 * inv_det);
  if (!__builtin_isfinite(w0) || !__builtin_isfinite(w1) || !__builtin_isfinite(w2)) return false;
  *t = tf;
  *b0 = w0;
  *b1 = w1;
  *b2 = w2;
  return true;
}
