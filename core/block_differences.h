// Error estimates of one stratified (Owen-scrambled Sobol) sequence from its own samples: differences of sibling
// sample blocks. Samples [k 2^j, (k+1) 2^j) of a pixel form a scrambled (0,j,2)-net in every 2D draw, so for block
// means m of size b, E[(m_left - m_right)^2] / 4 = h(b) = Var_b - Var_2b exactly, where Var_b is the variance of a
// b-sample mean; the variance of the n-sample mean is the sum of h over the block sizes b >= n, which the samples do
// not contain and which is extrapolated from the sizes below n.
#pragma once

#include <array>
#include <cstdint>

namespace tessera {

/// Running sums of squared sibling-block differences of one scalar sample stream, in sample order (a pure function
/// of the samples).
class BlockDifferences {
 public:
  /// Levels kept: block sizes 1 .. 2^(kLevels-1) (sibling pairs up to 2^kLevels samples).
  static constexpr int kLevels = 20;
  /// Adds the next sample.
  void add(double x);
  /// Samples added.
  uint32_t count() const { return n_; }
  /// h(2^level): mean over the complete sibling pairs of blocks of 2^level samples of (difference of means)^2 / 4;
  /// 0 without a complete pair.
  double h(int level) const;
  /// The i.i.d.-exact estimate of the n-sample mean's variance for a power-of-two n >= 2: h(n/2) (equal to
  /// variance / n for independent samples, larger than the true variance for stratified ones).
  double half_difference() const;
  /// Variance of the mean extrapolated over the block sizes, for a power-of-two n >= 8: the decay per doubling
  /// r = (h(n/2) + 2 h(n/4)) / (h(n/4) + 2 h(n/8)) (the top three levels, each ratio weighted by its pairs), clamped
  /// to [1/16, 1/2] (a 2D scrambled net's variance falls between n^-1 for any integrand and n^-3 for smooth ones;
  /// 1/16 leaves room for noise), then sum over b >= n of h(b) = h(n/2) r / (1 - r). At n = 4 the rate is
  /// h(2) / h(1); at n = 2 it is half_difference(); 0 below. Other counts use their largest power-of-two prefix's
  /// levels as if they were complete, so use it on powers of two.
  double extrapolated() const;

 private:
  std::array<double, kLevels> open_{};  // sum of the incomplete left block of each level (bit j of n_ set)
  std::array<double, kLevels> sq_{};    // sum over complete sibling pairs of ((mean_l - mean_r) / 2)^2
  uint32_t n_ = 0;
};

}  // namespace tessera
