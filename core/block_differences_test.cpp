// BlockDifferences: exact sibling sums, the i.i.d. identity h(n/2) = variance / n, and the extrapolation's bounds.
#include "core/block_differences.h"

#include <gtest/gtest.h>

#include <random>

namespace tessera {
namespace {

TEST(BlockDifferences, SumsSquaredSiblingDifferencesPerLevel) {
  BlockDifferences b;
  for (double x : {1.0, 3.0, 2.0, 2.0}) b.add(x);
  EXPECT_EQ(b.count(), 4U);
  EXPECT_DOUBLE_EQ(b.h(0), 0.5);  // pairs (1,3) and (2,2): ((1-3)/2)^2 = 1 and 0, over 2 pairs
  EXPECT_DOUBLE_EQ(b.h(1), 0.0);  // block means 2 and 2
  EXPECT_DOUBLE_EQ(b.half_difference(), 0.0);
  b.add(5.0);  // an open block counts in no level
  EXPECT_DOUBLE_EQ(b.h(0), 0.5);
  EXPECT_DOUBLE_EQ(b.h(2), 0.0);
  EXPECT_DOUBLE_EQ(BlockDifferences{}.extrapolated(), 0.0);
}

TEST(BlockDifferences, HalfDifferenceIsTheVarianceOfTheMeanForIndependentSamples) {
  // Uniform samples: variance 1/12, so a 16-sample mean has variance 1/192; over 20000 sequences the average of
  // h(n/2) (one pair each) is within 3% (its relative deviation is sqrt(2/20000) = 1%).
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr int kRuns = 20000;
  double mean_h = 0, mean_ext = 0;
  for (int r = 0; r < kRuns; ++r) {
    BlockDifferences b;
    for (int i = 0; i < 16; ++i) b.add(u(rng));
    mean_h += b.half_difference() / kRuns;
    mean_ext += b.extrapolated() / kRuns;
  }
  EXPECT_NEAR(mean_h * 192.0, 1.0, 0.03);
  // Independent samples decay by 1/2 per doubling: the extrapolation's ratio is clamped at 1/2 (r / (1 - r) <= 1),
  // and its noisy ratio often falls below, so it under-predicts here, but by less than 2x.
  EXPECT_LT(mean_ext * 192.0, 1.0);
  EXPECT_GT(mean_ext * 192.0, 0.5);
}

TEST(BlockDifferences, ExtrapolatesAGeometricDecay) {
  // Pairs differing by 4 (h(1 sample) = 4), blocks of 2 with means 1.5, -0.5, 0.5, -1.5 (h(2) = 1), halves with
  // means 0.5, -0.5 (h(4) = 1/4): r = (1/4 + 2 x 1) / (1 + 2 x 4) = 1/4, so the variance of the 8-sample mean is
  // extrapolated as h(4) r / (1 - r) = 1/12.
  BlockDifferences b;
  for (double x : {3.5, -0.5, 1.5, -2.5, 2.5, -1.5, 0.5, -3.5}) b.add(x);
  EXPECT_DOUBLE_EQ(b.h(0), 4.0);
  EXPECT_DOUBLE_EQ(b.h(1), 1.0);
  EXPECT_DOUBLE_EQ(b.h(2), 0.25);
  EXPECT_DOUBLE_EQ(b.half_difference(), 0.25);
  EXPECT_DOUBLE_EQ(b.extrapolated(), 1.0 / 12.0);
}

}  // namespace
}  // namespace tessera
