// Test-only: the spp of the CLI tests' renders scaled by TESSERA_TEST_SPP_SCALE (N or 1/N, default 1), the same knob
// tests/farm/common.sh reads, to show that no outcome depends on how long a render takes (docs/testing.md).
#pragma once

#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace tessera::testing {

/// n samples per pixel times the scale (at least 1); throws for a malformed TESSERA_TEST_SPP_SCALE.
inline uint32_t scaled_spp(uint32_t n) {
  const char* env = std::getenv("TESSERA_TEST_SPP_SCALE");
  const std::string s = env && *env ? env : "1";
  const size_t slash = s.find('/');
  size_t used_num = 0, used_den = 0;
  uint64_t num = 0, den = 1;
  try {
    num = std::stoull(s.substr(0, slash), &used_num);
    if (slash != std::string::npos) den = std::stoull(s.substr(slash + 1), &used_den);
  } catch (const std::exception&) {
    num = 0;
  }
  const bool whole = used_num == (slash == std::string::npos ? s.size() : slash) &&
                     (slash == std::string::npos || used_den == s.size() - slash - 1);
  if (!whole || num == 0 || den == 0) throw std::invalid_argument("TESSERA_TEST_SPP_SCALE must be N or 1/N, not '" + s + "'");
  const uint64_t v = uint64_t(n) * num / den;
  return uint32_t(v < 1 ? 1 : v);
}

}  // namespace tessera::testing
