// The BVH traversal kernels for SimdPath::kAvx512 (flags in core/CMakeLists.txt); the source is core/geometry/kernels/bvh_traverse.inl.
#include "core/geometry/kernels/bvh_kernels.h"

#include <immintrin.h>

namespace tessera::bvh_kernels {
namespace avx512 {
#include "core/geometry/kernels/bvh_traverse.inl"
}  // namespace avx512

extern const Kernels kAvx512 = {&avx512::intersect, &avx512::occluded};

}  // namespace tessera::bvh_kernels
