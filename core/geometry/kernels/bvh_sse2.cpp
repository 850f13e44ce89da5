// The BVH traversal kernels for SimdPath::kSse2 (flags in core/CMakeLists.txt); the source is core/geometry/kernels/bvh_traverse.inl.
#include "core/geometry/kernels/bvh_kernels.h"

#include <immintrin.h>

namespace tessera::bvh_kernels {
namespace sse2 {
#include "core/geometry/kernels/bvh_traverse.inl"
}  // namespace sse2

extern const Kernels kSse2 = {&sse2::intersect, &sse2::occluded};

}  // namespace tessera::bvh_kernels
