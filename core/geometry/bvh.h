// Bounding volume hierarchy over triangles and spheres: binned-SAH build of an 8-wide tree (tiny scenes: one node
// over leaves grouped bottom-up) with SIMD node and 8-primitive leaf tests, closest-hit and any-hit queries through
// kernels chosen at run time (core/util/simd_path.h).
#pragma once

#include "core/geometry/bounds.h"
#include "core/geometry/split_method.h"
#include "core/geometry/bvh_layout.h"
#include "core/geometry/ray.h"
#include "core/util/simd_path.h"
#include "core/geometry/sphere.h"
#include "core/geometry/triangle.h"

#include <cstddef>
#include <cstdint>
#include <new>
#include <optional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

namespace tessera {

/// The closest intersection along a ray. Primitive ids below triangle_count() are triangles, the rest are
/// spheres (sphere index = prim - triangle_count()).
struct Hit {
  float t;        ///< Ray parameter.
  float b1, b2;   ///< Barycentric weights of p1 and p2 (triangles only; b0 = 1 - b1 - b2).
  uint32_t prim;  ///< Primitive id.
};

/// Build parameters.
struct BvhOptions {
  SplitMethod split = SplitMethod::kSah;  ///< Split strategy.
  int max_leaf_prims = 8;                 ///< Upper bound on primitives per leaf when a split is possible (binned
                                          ///< and median builds; scenes of at most 64 primitives built with kSah
                                          ///< are grouped into at most 8 leaves of up to 16 instead).
  int bins = 16;                          ///< SAH bins per axis.
};

/// Shape of a built hierarchy (the traced tree is bvh_layout::kNodeWidth wide).
struct BvhStats {
  size_t nodes = 0;         ///< Total nodes: interior nodes plus leaves.
  size_t leaves = 0;        ///< Leaf nodes.
  int max_depth = 0;        ///< Deepest leaf (root = 0).
  double sah_cost = 0.0;    ///< Expected cost per ray (node visit 1, one primitive 1), relative to the root area.
};

namespace detail {
/// Allocates bytes aligned to align; blocks of 2 MiB or more are 2 MiB aligned and, on Linux, advised to use
/// transparent huge pages (random BVH traversal would otherwise miss the TLB on most node visits).
void* allocate_large(size_t bytes, size_t align);
/// Releases a block from allocate_large() with the same size and alignment.
void deallocate_large(void* p, size_t bytes, size_t align) noexcept;

/// A std::allocator replacement that leaves trivially constructible elements uninitialised on resize().
template <class T>
struct UninitAllocator {
  using value_type = T;  ///< Allocated type.
  UninitAllocator() = default;
  /// Rebinding constructor.
  template <class U>
  UninitAllocator(const UninitAllocator<U>&) noexcept {}
  /// Storage for n elements, aligned for T.
  T* allocate(size_t n) { return static_cast<T*>(allocate_large(n * sizeof(T), alignof(T))); }
  /// Releases storage from allocate().
  void deallocate(T* p, size_t n) noexcept { deallocate_large(p, n * sizeof(T), alignof(T)); }
  /// Default-initialises (does not zero) an element.
  template <class U>
  void construct(U* p) noexcept { ::new (static_cast<void*>(p)) U; }
  /// Constructs an element from arguments.
  template <class U, class... A>
  void construct(U* p, A&&... a) { ::new (static_cast<void*>(p)) U(std::forward<A>(a)...); }
  /// All instances are interchangeable.
  friend bool operator==(const UninitAllocator&, const UninitAllocator&) { return true; }
};
}  // namespace detail

/// An immutable BVH. Thread-safe for concurrent queries once built.
class Bvh {
 public:
  /// Maximum depth a built tree reaches; traversal stacks are sized by it.
  static constexpr int kMaxDepth = bvh_layout::kMaxDepth;

  Bvh() = default;

  /// Builds a hierarchy over copies of the given primitives (uses all TBB worker threads).
  static Bvh build(std::span<const Triangle> triangles, std::span<const Sphere> spheres,
                   const BvhOptions& options = {});

  /// Closest hit in (0, r.tmax), or nothing; invalid rays (NaN, zero direction) never hit. Of hits at the same
  /// distance the one with the lowest primitive id is returned, whatever the tree's shape and the SimdPath.
  std::optional<Hit> intersect(const Ray& r) const;

  /// True when anything is hit in (0, r.tmax); stops at the first hit found.
  bool occluded(const Ray& r) const;

  /// Number of triangles (ids [0, triangle_count())).
  uint32_t triangle_count() const { return num_triangles_; }
  /// Number of spheres (ids [triangle_count(), triangle_count() + sphere_count())).
  uint32_t sphere_count() const { return num_spheres_; }
  /// Bounds of everything in the hierarchy.
  Bounds3 bounds() const { return bounds_; }
  /// Node count, depth and SAH cost of the built tree.
  BvhStats stats() const;
  /// Bytes of the acceleration structure: nodes and leaf packets (which hold copies of the primitives).
  size_t memory_bytes() const;

  /// The kernels queries run: best_simd_path() unless set_simd_path() chose another.
  SimdPath simd_path() const { return path_; }
  /// Runs later queries with path p's kernels (for tests and benchmarks: every path returns bitwise the same hits).
  /// Throws std::invalid_argument when this CPU cannot run p.
  void set_simd_path(SimdPath p);

 private:
  using Node = bvh_layout::Node;
  using Packet = bvh_layout::Packet;

  struct Builder;

  // Sized exactly once the binary tree is built; filled in parallel, each subtree in ranges of its own.
  std::vector<Node, detail::UninitAllocator<Node>> nodes_;
  std::vector<Packet, detail::UninitAllocator<Packet>> packets_;
  Bounds3 bounds_;
  uint32_t num_triangles_ = 0;
  uint32_t num_spheres_ = 0;
  SimdPath path_ = best_simd_path();
};

}  // namespace tessera
