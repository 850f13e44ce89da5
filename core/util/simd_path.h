// The instruction sets the BVH's traversal kernels are compiled for, and which of them this CPU can run.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

namespace tessera {

/// A set of traversal kernels, each compiled for one x86-64 instruction set. Every path returns bitwise the same
/// hits (core/geometry/bvh.h), so the choice changes speed only.
enum class SimdPath : uint8_t {
  kSse2,    ///< Baseline x86-64: SSE2.
  kAvx2,    ///< AVX2 with BMI1/BMI2 and POPCNT.
  kAvx512,  ///< AVX-512 F, VL, BW and DQ on top of the AVX2 path's set.
};

/// Names of the SimdPath values, in declaration order.
inline constexpr std::string_view kSimdPathNames[] = {"sse2", "avx2", "avx512"};

/// True when this CPU and operating system can run path p.
bool simd_path_supported(SimdPath p);

/// The widest path this CPU runs, found once from cpuid; new BVHs use it.
SimdPath best_simd_path();

/// Every path this CPU runs, narrowest first.
std::vector<SimdPath> supported_simd_paths();

}  // namespace tessera
