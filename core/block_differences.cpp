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
  // Pairs-weighted ratio of consecutive levels: level top has 1 pair, top - 1 has 2 (at n = 4 only one ratio).
  double num = h(top), den = h(top - 1);
  if (top >= 2) {
    num += 2.0 * h(top - 1);
    den += 2.0 * h(top - 2);
  }
  const double r = den > 0.0 ? std::clamp(num / den, 1.0 / 16.0, 0.5) : 0.5;
  return h(top) * r / (1.0 - r);
}

}  // namespace tessera
