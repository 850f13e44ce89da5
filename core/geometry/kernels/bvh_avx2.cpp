// The BVH traversal kernels for SimdPath::kAvx2 (flags in core/CMakeLists.txt); the source is core/geometry/kernels/bvh_traverse.inl.
#include "core/geometry/kernels/bvh_kernels.h"

#include <immintrin.h>

namespace tessera::bvh_kernels {
namespace avx2 {
#include "core/geometry/kernels/bvh_traverse.inl"
}  // namespace avx2

extern const Kernels kAvx2 = {&avx2::intersect, &avx2::occluded};

}  // namespace tessera::bvh_kernels
