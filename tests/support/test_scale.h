// Test-only: how many random cases a test runs. Sanitizer builds define TESSERA_TEST_SCALE_DIVISOR to run a
// fraction of the main build's counts (the main build's counts are the ones the issues ask for).
#pragma once

#include <cstddef>

namespace tessera::testing {

#ifdef TESSERA_TEST_SCALE_DIVISOR
inline constexpr size_t kScaleDivisor = TESSERA_TEST_SCALE_DIVISOR;
#else
inline constexpr size_t kScaleDivisor = 1;
#endif

/// The number of cases to run: n in the main build, n / divisor (at least 1) under sanitizers.
constexpr size_t scaled(size_t n) { return n / kScaleDivisor > 0 ? n / kScaleDivisor : 1; }

}  // namespace tessera::testing
