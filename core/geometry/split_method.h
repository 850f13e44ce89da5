// The BVH's split strategies and their names, as scenes and the command line choose them.
#pragma once

#include <string_view>

namespace tessera {

/// How interior nodes are split.
enum class SplitMethod {
  kSah,     ///< Binned surface-area heuristic over all three axes (default).
  kMedian,  ///< Object median along the longest centroid axis (the baseline to beat).
};

/// Names of the SplitMethod values (scene key integrator.bvh, --bvh), in declaration order.
inline constexpr std::string_view kSplitMethodNames[] = {"sah", "median"};

}  // namespace tessera
