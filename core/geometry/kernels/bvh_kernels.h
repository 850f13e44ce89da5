// The BVH's traversal kernels: one set per SimdPath, each compiled in its own file with that instruction set's
// flags (core/geometry/kernels/bvh_sse2.cpp, bvh_avx2.cpp, bvh_avx512.cpp, all from core/geometry/kernels/bvh_traverse.inl) and chosen at run time.
// Every set computes the same IEEE operations per lane in the same order and visits the same nodes in the same
// order, so all return bitwise the same hit. Plain types only, for the reason given in core/geometry/bvh_layout.h.
#pragma once

#include "core/geometry/bvh_layout.h"

#include <cstdint>

namespace tessera {

struct Ray;

namespace bvh_kernels {

/// A query's ray: core/geometry/ray.h's Ray as plain floats, and the Ray itself for sphere tests.
struct RayData {
  float o[3];      ///< Origin.
  float d[3];      ///< Direction.
  float tmax;      ///< Far end of the ray.
  const Ray* ray;  ///< The same ray.
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
  float far_scale;                    ///< 1 + 2 gamma(3): the slab test's conservative widening of far distances.
};

/// One SimdPath's kernels. Both check the ray as Ray::valid() does (an invalid ray hits nothing) and compute the
/// per-ray constants of BoxRay (core/geometry/bounds.h) and WatertightRay (core/geometry/triangle.h) bitwise.
struct Kernels {
  /// Closest hit in (0, r.tmax); fills *hit and returns true when there is one.
  bool (*intersect)(const Tree& tree, const RayData& r, HitRecord* hit);
  /// True when anything is hit in (0, r.tmax).
  bool (*occluded)(const Tree& tree, const RayData& r);
};

/// The SSE2 kernels (core/geometry/kernels/bvh_sse2.cpp).
extern const Kernels kSse2;
/// The AVX2 kernels (core/geometry/kernels/bvh_avx2.cpp).
extern const Kernels kAvx2;
/// The AVX-512 kernels (core/geometry/kernels/bvh_avx512.cpp).
extern const Kernels kAvx512;

/// intersect_sphere (core/geometry/sphere.h) of ray with the sphere (c, radius) in (0, tmax); compiled for the baseline ISA
/// in core/geometry/bvh.cpp.
bool sphere_hit(const Ray& ray, float cx, float cy, float cz, float radius, float tmax, float* t);

}  // namespace bvh_kernels
}  // namespace tessera
