// The BVH's traversal kernels: one set per SimdPath, each compiled in its own file with that instruction set's
// flags (core/bvh_sse2.cpp, bvh_avx2.cpp, bvh_avx512.cpp, all from core/bvh_traverse.inl) and chosen at run time.
// Every set computes the same IEEE operations per lane in the same order and visits the same nodes in the same
// order, so all return bitwise the same hit. Plain types only, for the reason given in core/bvh_layout.h.
#pragma once

#include "core/bvh_layout.h"

#include <cstdint>

namespace tessera {

struct Ray;

namespace bvh_kernels {

/// Per-ray constants, computed once per query by core/bvh.cpp.
struct TraceRay {
  float o[3];                   ///< Origin (slab test).
  float inv_d[3];               ///< 1 / direction, +-inf for zero components (BoxRay in core/bounds.h).
  int near_row[3], far_row[3];  ///< Rows of Node::box holding each axis's near and far plane for this direction.
  float far_scale;              ///< 1 + 2 gamma(3): the far distance's conservative widening.
  int kx, ky, kz;               ///< The watertight test's axis permutation (WatertightRay in core/triangle.h).
  float ox, oy, oz;             ///< Origin in the permuted axes.
  float sx, sy, sz;             ///< Shear constants.
  float tmax;                   ///< Far end of the ray.
  const Ray* ray;               ///< The ray itself, for sphere tests.
};

/// A closest hit as the kernels report it.
struct HitRecord {
  float t;        ///< Ray parameter.
  float b1, b2;   ///< Barycentric weights of p1 and p2.
  uint32_t prim;  ///< Primitive id.
};

/// A built tree as the kernels see it.
struct Tree {
  const bvh_layout::Node* nodes;      ///< Interior nodes; the root is nodes[0].
  const bvh_layout::Packet* packets;  ///< Leaf packets.
  uint32_t num_triangles;             ///< Primitive ids below this are triangles, the rest spheres.
};

/// One SimdPath's kernels.
struct Kernels {
  /// Closest hit of a valid ray in (0, r.tmax); fills *hit and returns true when there is one.
  bool (*intersect)(const Tree& tree, const TraceRay& r, HitRecord* hit);
  /// True when anything is hit in (0, r.tmax).
  bool (*occluded)(const Tree& tree, const TraceRay& r);
};

/// The SSE2 kernels (core/bvh_sse2.cpp).
extern const Kernels kSse2;
/// The AVX2 kernels (core/bvh_avx2.cpp).
extern const Kernels kAvx2;
/// The AVX-512 kernels (core/bvh_avx512.cpp).
extern const Kernels kAvx512;

/// The watertight test's double-precision finish (detail::intersect_sheared_double in core/triangle.h) on sheared
/// vertices s = {ax, ay, az, bx, by, bz, cx, cy, cz}; compiled for the baseline ISA in core/bvh.cpp.
bool triangle_fallback(const float (&s)[9], float sz, float tmax, HitRecord* out);

/// intersect_sphere (core/sphere.h) of r's ray with the sphere (c, radius) in (0, tmax); compiled for the
/// baseline ISA in core/bvh.cpp.
bool sphere_hit(const TraceRay& r, float cx, float cy, float cz, float radius, float tmax, float* t);

}  // namespace bvh_kernels
}  // namespace tessera
