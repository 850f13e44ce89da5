// Detection of exactly coincident triangles (the same three vertices in any order), which make the visible
// surface depend on BVH traversal order (z-fighting) and usually mean a scene lists the same mesh twice.
#pragma once

#include "core/geometry/triangle.h"

#include <cstdint>
#include <span>
#include <vector>

namespace tessera {

/// Two triangles with bitwise identical vertex sets; first < second (indices into the searched span).
struct CoincidentPair {
  uint32_t first;   ///< Earlier triangle.
  uint32_t second;  ///< Later triangle.
};

/// Every triangle that coincides with an earlier one, paired with the earliest such triangle, in index order.
/// Expected O(n): vertices are sorted per triangle and hashed by their bits (-0 and +0 count as equal).
std::vector<CoincidentPair> find_coincident_triangles(std::span<const Triangle> triangles);

}  // namespace tessera
