// The BVH's memory layout, shared by its builder (core/geometry/bvh.cpp) and its traversal kernels (core/geometry/kernels/bvh_kernels.h).
// Plain types and constants only: the kernels are compiled once per instruction set and must not instantiate
// inline code that other files share.
#pragma once

#include <cstdint>

namespace tessera::bvh_layout {

/// Children per interior node.
inline constexpr int kNodeWidth = 8;
/// Primitives per leaf packet.
inline constexpr int kPacketWidth = 8;
/// Maximum depth of a built tree; traversal stacks are sized by it.
inline constexpr int kMaxDepth = 96;

/// Set in a child reference that names a leaf; the rest is the index of the leaf's first packet (its packets run
/// to the one flagged kLastPacket). Without it, the reference is the index of an interior node.
inline constexpr uint32_t kLeafBit = 0x80000000u;
/// Set in id[0] of a leaf's last packet.
inline constexpr uint32_t kLastPacket = 0x80000000u;
/// Id of an unused packet lane (lane 0 is always used).
inline constexpr uint32_t kNoPrim = 0xffffffffu;

/// An interior node: the child boxes as structure of arrays, so one slab test covers all of them. box[2a][k] and
/// box[2a+1][k] are the low and high planes of child k on axis a. Unused slots hold an empty box (lo = +inf,
/// hi = -inf), which no ray enters.
struct alignas(64) Node {
  float box[6][kNodeWidth];     ///< Child boxes, structure of arrays.
  uint32_t child[kNodeWidth];   ///< Child references.
  uint32_t pad[8];              ///< Zero; pads the node to four cache lines.
};
static_assert(sizeof(Node) == 256);

/// kPacketWidth primitives of one kind, structure of arrays. Triangles: v[vertex][axis][lane]. Spheres:
/// v[0][axis][lane] is the centre and v[1][0][lane] the radius. id[lane] is the primitive id (kNoPrim if unused);
/// id[0] also carries kLastPacket.
struct alignas(32) Packet {
  float v[3][3][kPacketWidth];  ///< Vertices or sphere data.
  uint32_t id[kPacketWidth];    ///< Primitive ids.
};
static_assert(sizeof(Packet) == 320);

}  // namespace tessera::bvh_layout
