// Error estimates of one stratified (Owen-scrambled Sobol) sequence from its own samples: differences of sibling
// sample blocks. Samples [k 2^j, (k+1) 2^j) of a pixel form a scrambled (0,j,2)-net in every 2D draw, so for block
// means m of size b, E[(m_left - m_right)^2] / 4 = h(b) = Var_b - Var_2b exactly, where Var_b is the variance of a
// b-sample mean; the variance of the n-sample mean is the sum of h over the block sizes b >= n, which the samples do
// not contain and which is extrapolated from the sizes below n (docs/error-estimates.md measures how well).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

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
  /// h(1), h(2), ..., h(2^top) with 2^top = n/2 the largest block size that has a complete pair (empty below 2).
  std::vector<double> levels() const;
  /// The i.i.d.-exact estimate of the n-sample mean's variance for a power-of-two n >= 2: h(n/2) (equal to
  /// variance / n for independent samples, larger than the true variance for stratified ones).
  double half_difference() const;
  /// pooled_rate(levels()).
  double extrapolated() const;
  /// two_doubling_rate(levels()).
  double two_doubling() const;

  // Extrapolations as functions of the levels alone (the last one being h(n/2) of a power-of-two n), so that they
  // also apply to levels averaged over renders. Each is h(n/2) r / (1 - r), the sum over b >= n of a geometric
  // continuation with decay r per doubling, r clamped to [1/16, 1/2] (a scrambled 2D net's variance falls between
  // n^-1, any square-integrable integrand, and about n^-3, smooth ones; 1/16 leaves room for noise).

  /// r from the top three levels, each ratio weighted by its pairs: (h(n/2) + 2 h(n/4)) / (h(n/4) + 2 h(n/8)); at
  /// n = 4 h(2) / h(1), at n = 2 no extrapolation (h(1)); 0 below.
  static double pooled_rate(std::span<const double> levels);
  /// r^2 from two doublings of the top four levels: (h(n/2) + 2 h(n/4)) / (h(n/8) + 2 h(n/16)). A (0,m,2)-net's
  /// levels alternate between odd and even m (an axis-aligned edge is cut by every other level's strata), and a
  /// ratio of equal mixes of adjacent levels cancels that. Below 16 samples pooled_rate.
  static double two_doubling_rate(std::span<const double> levels);
  /// The same r^2 from the four levels below the top, (h(n/4) + 2 h(n/8)) / (h(n/16) + 2 h(n/32)), so that it does
  /// not share a sample difference with h(n/2) (h(n/4) / h(n/16) at n = 16); below 16 samples pooled_rate.
  static double two_doubling_rate_below(std::span<const double> levels);

 private:
  std::array<double, kLevels> open_{};  // sum of the incomplete left block of each level (bit j of n_ set)
  std::array<double, kLevels> sq_{};    // sum over complete sibling pairs of ((mean_l - mean_r) / 2)^2
  uint32_t n_ = 0;
};

}  // namespace tessera
