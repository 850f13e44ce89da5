#include "core/sampling/block_differences.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace tessera {

namespace {

// h(n/2) r / (1 - r) for a decay r per doubling, clamped to [1/16, 1/2] (1/2 when the denominator is 0).
double geometric_tail(double top, double num, double den, bool per_two_doublings) {
  double r = 0.5;
  if (den > 0.0) {
    const double ratio = num / den;
    r = std::clamp(per_two_doublings ? std::sqrt(ratio) : ratio, 1.0 / 16.0, 0.5);
  }
  return top * r / (1.0 - r);
}

}  // namespace

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

std::vector<double> BlockDifferences::levels() const {
  std::vector<double> out;
  if (n_ < 2) return out;
  const int top = std::min(int(std::bit_width(n_)) - 2, kLevels - 1);
  for (int j = 0; j <= top; ++j) out.push_back(h(j));
  return out;
}

double BlockDifferences::half_difference() const {
  if (n_ < 2) return 0.0;
  return h(std::bit_width(n_) - 2);
}

double BlockDifferences::extrapolated() const { return pooled_rate(levels()); }

double BlockDifferences::two_doubling() const { return two_doubling_rate(levels()); }

double BlockDifferences::pooled_rate(std::span<const double> h) {
  const size_t m = h.size();
  if (m == 0) return 0.0;
  if (m == 1) return h[0];
  if (m == 2) return geometric_tail(h[1], h[1], h[0], false);
  return geometric_tail(h[m - 1], h[m - 1] + 2.0 * h[m - 2], h[m - 2] + 2.0 * h[m - 3], false);
}

double BlockDifferences::two_doubling_rate(std::span<const double> h) {
  const size_t m = h.size();
  if (m < 4) return pooled_rate(h);
  return geometric_tail(h[m - 1], h[m - 1] + 2.0 * h[m - 2], h[m - 3] + 2.0 * h[m - 4], true);
}

double BlockDifferences::two_doubling_rate_below(std::span<const double> h) {
  const size_t m = h.size();
  if (m < 4) return pooled_rate(h);
  if (m == 4) return geometric_tail(h[3], h[2], h[0], true);
  return geometric_tail(h[m - 1], h[m - 2] + 2.0 * h[m - 3], h[m - 4] + 2.0 * h[m - 5], true);
}

}  // namespace tessera
