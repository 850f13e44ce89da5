#include "core/util/simd_path.h"

namespace tessera {

bool simd_path_supported(SimdPath p) {
#if defined(__x86_64__) || defined(__i386__)
  // __builtin_cpu_supports also checks that the OS saves the YMM/ZMM state (XGETBV) for the AVX features.
  switch (p) {
    case SimdPath::kSse2:
      return true;
    case SimdPath::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2") &&
             __builtin_cpu_supports("popcnt");
    case SimdPath::kAvx512:
      return simd_path_supported(SimdPath::kAvx2) && __builtin_cpu_supports("avx512f") &&
             __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512dq");
  }
  return false;
#else
  return p == SimdPath::kSse2;
#endif
}

SimdPath best_simd_path() {
  static const SimdPath best = simd_path_supported(SimdPath::kAvx512) ? SimdPath::kAvx512
                               : simd_path_supported(SimdPath::kAvx2) ? SimdPath::kAvx2
                                                                      : SimdPath::kSse2;
  return best;
}

std::vector<SimdPath> supported_simd_paths() {
  std::vector<SimdPath> out;
  for (SimdPath p : {SimdPath::kSse2, SimdPath::kAvx2, SimdPath::kAvx512})
    if (simd_path_supported(p)) out.push_back(p);
  return out;
}

}  // namespace tessera
