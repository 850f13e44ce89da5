#include "core/block_differences.h"

#include <algorithm>
#include <bit>

namespace tessera {

void BlockDifferences::add(double x) {
  double carry = x;  // sum of the block of 2^j samples that just completed
  for (int j = 0; j < kLevels; ++j) {
    if (!((n_ >> j) & 1U)) {
      open_[size_t(j)] = carry;
      break;
    }
    const double d = (open_[size_t(j)] - carry) / double(1U << j) / 2.0;
    sq_[size_t(j)] += d * d;
    carry += open_[size_t(j)];
  }
  ++n_;
}

double BlockDifferences::h(int level) const {
  if (level < 0 || level >= kLevels) return 0.0;
  const uint32_t pairs = n_ >> (level + 1);
  return pairs ? sq_[size_t(level)] / double(pairs) : 0.0;
}

double BlockDifferences::half_difference() const {
  if (n_ < 2) return 0.0;
  return h(std::bit_width(n_) - 2);
}

double BlockDifferences::extrapolated() const {
  if (n_ < 4) return half_difference();
  const int top = std::bit_width(n_) - 2;  // level of the two halves
  const double upper = h(top), lower = h(top - 1);
  const double r = lower > 0.0 ? std::clamp(upper / lower, 1.0 / 16.0, 0.5) : 0.5;
  return upper * r / (1.0 - r);
}

}  // namespace tessera
