// Bounding volume hierarchy over triangles and spheres: binned-SAH build, closest-hit and any-hit queries.
#pragma once

#include "core/bounds.h"
#include "core/ray.h"
#include "core/sphere.h"
#include "core/triangle.h"

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace tessera {

/// The closest intersection along a ray. Primitive ids below triangle_count() are triangles, the rest are
/// spheres (sphere index = prim - triangle_count()).
struct Hit {
  float t;        ///< Ray parameter.
  float b1, b2;   ///< Barycentric weights of p1 and p2 (triangles only; b0 = 1 - b1 - b2).
  uint32_t prim;  ///< Primitive id.
};

/// How interior nodes are split.
enum class SplitMethod {
  kSah,     ///< Binned surface-area heuristic over all three axes (default).
  kMedian,  ///< Object median along the longest centroid axis (the baseline to beat).
};

/// Build parameters.
struct BvhOptions {
  SplitMethod split = SplitMethod::kSah;  ///< Split strategy.
  int max_leaf_prims = 4;                 ///< Upper bound on primitives per leaf when a split is possible.
  int bins = 16;                          ///< SAH bins per axis.
};

/// Shape of a built hierarchy.
struct BvhStats {
  size_t nodes = 0;         ///< Total nodes.
  size_t leaves = 0;        ///< Leaf nodes.
  int max_depth = 0;        ///< Deepest leaf (root = 0).
  double sah_cost = 0.0;    ///< Expected cost per ray (traversal 1, intersection 1), relative to the root area.
};

/// An immutable BVH. Thread-safe for concurrent queries once built.
class Bvh {
 public:
  /// Maximum depth a built tree reaches; traversal stacks are sized by it.
  static constexpr int kMaxDepth = 96;

  Bvh() = default;

  /// Builds a hierarchy over copies of the given primitives (uses all TBB worker threads).
  static Bvh build(std::span<const Triangle> triangles, std::span<const Sphere> spheres,
                   const BvhOptions& options = {});

  /// Closest hit in (0, r.tmax), or nothing; invalid rays (NaN, zero direction) never hit.
  std::optional<Hit> intersect(const Ray& r) const;

  /// True when anything is hit in (0, r.tmax); stops at the first hit found.
  bool occluded(const Ray& r) const;

  /// Number of triangles (ids [0, triangle_count())).
  uint32_t triangle_count() const { return num_triangles_; }
  /// Number of spheres (ids [triangle_count(), triangle_count() + sphere_count())).
  uint32_t sphere_count() const { return num_spheres_; }
  /// Bounds of everything in the hierarchy.
  Bounds3 bounds() const { return nodes_.empty() ? Bounds3{} : Bounds3{nodes_[0].lo, nodes_[0].hi}; }
  /// Node count, depth and SAH cost of the built tree.
  BvhStats stats() const;

 private:
  // 32 bytes. Interior: first child follows the node, `offset` is the second child. Leaf: `count` > 0
  // primitives from `offset` in prims_.
  struct Node {
    Vec3 lo;
    uint32_t offset;
    Vec3 hi;
    uint16_t count;
    uint8_t axis;
    uint8_t pad;
  };
  static_assert(sizeof(Node) == 32);

  // Leaf-ordered primitive geometry: a triangle's vertices, or a sphere's centre in a and radius in b.x.
  struct PrimData {
    Vec3 a, b, c;
  };

  struct Builder;

  std::vector<Node> nodes_;
  std::vector<PrimData> prims_;
  std::vector<uint32_t> prim_ids_;
  uint32_t num_triangles_ = 0;
  uint32_t num_spheres_ = 0;
};

}  // namespace tessera
