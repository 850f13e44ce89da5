// BlockDifferences: exact sibling sums, the identity h(b) = Var_b - Var_2b on the pixel sampler's own streams, the
// i.i.d. identity h(n/2) = variance / n, and the extrapolations on geometric levels.
#include "core/sampling/block_differences.h"

#include "core/sampling/sampler.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <random>
#include <vector>

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
  // Over two doublings the same clamp and noisy ratio under-predict too (0.87 of the truth here).
  double mean_two = 0;
  std::mt19937_64 rng2(6);
  for (int r = 0; r < kRuns; ++r) {
    BlockDifferences b;
    for (int i = 0; i < 16; ++i) b.add(u(rng2));
    mean_two += b.two_doubling() / kRuns;
  }
  EXPECT_LT(mean_two * 192.0, 0.95);
  EXPECT_GT(mean_two * 192.0, 0.75);
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

TEST(BlockDifferences, TwoDoublingRateCancelsTheAlternationOfOddAndEvenLevels) {
  // Levels falling by 1/4 per doubling, the odd ones twice as high (as an axis-aligned edge alternates): the rate over
  // two doublings is (8 + 2 x 16) / (128 + 2 x 256) = 1/16, i.e. 1/4 per doubling, and the tail 8 (1/4 + 1/16 + ...)
  // = 8/3; one doubling at a time sees 1/8 and 1/2 by turns.
  const std::vector<double> alternating = {256, 128, 16, 8};
  EXPECT_DOUBLE_EQ(BlockDifferences::two_doubling_rate(alternating), 8.0 / 3.0);
  EXPECT_NEAR(BlockDifferences::pooled_rate(alternating), 8.0 * (40.0 / 272.0) / (1.0 - 40.0 / 272.0), 1e-12);
  // The rate from the four levels below the top: (32 + 2 x 64) / (512 + 2 x 1024) = 1/16, applied to h(n/2) = 4.
  EXPECT_DOUBLE_EQ(BlockDifferences::two_doubling_rate_below(std::vector<double>{1024, 512, 64, 32, 4}), 4.0 / 3.0);
  // Independent samples (h halves per doubling) need no extrapolation beyond h(n/2); no decay at all is clamped there.
  EXPECT_DOUBLE_EQ(BlockDifferences::two_doubling_rate(std::vector<double>{8, 4, 2, 1}), 1.0);
  EXPECT_DOUBLE_EQ(BlockDifferences::two_doubling_rate(std::vector<double>{1, 1, 1, 1}), 1.0);
  // Below 16 samples (four levels) the pooled rate stands in.
  EXPECT_DOUBLE_EQ(BlockDifferences::two_doubling_rate(std::vector<double>{4, 1, 0.25}),
                   BlockDifferences::pooled_rate(std::vector<double>{4, 1, 0.25}));
  // A stream's own levels: h(1) .. h(n/2) of its largest complete pairs.
  BlockDifferences b;
  for (double x : {3.5, -0.5, 1.5, -2.5, 2.5, -1.5, 0.5, -3.5}) b.add(x);
  EXPECT_EQ(b.levels(), (std::vector<double>{4.0, 1.0, 0.25}));
  EXPECT_DOUBLE_EQ(b.two_doubling(), b.extrapolated());
}

// What every estimate from a pixel's own samples rests on: each aligned block of 2^j of its samples is a scrambled net
// distributed as the first 2^j samples (a render at 2^j spp), so the sibling differences measure E h(b) = Var_b -
// Var_2b, with Var_b the variance of a b-spp render over seeds. Checked over seeds on the sampler's own streams for a
// smooth integrand, an edge and an edge in the pixel times an edge in a second draw (a shadow boundary seen across a
// pixel), each level within statistical noise (16% at 4096 seeds for the worst level, 5 standard deviations).
TEST(BlockDifferences, SiblingDifferencesMeasureTheVarianceDropOfThePixelSampler) {
  constexpr uint32_t kN = 64;
  constexpr int kLevelsChecked = 6;
  const int seeds = int(testing::scaled(4096));
  const std::vector<std::pair<const char*, double (*)(Vec2, Vec2)>> integrands = {
      {"linear", [](Vec2 u, Vec2) { return double(u.x); }},
      {"edge", [](Vec2 u, Vec2) { return u.x < 0.3f ? 1.0 : 0.0; }},
      {"edge x edge", [](Vec2 u, Vec2 v) { return (u.x < 0.3f ? 1.0 : 0.0) * (v.y < 0.6f ? 1.0 : 0.0); }}};
  for (const auto& [name, f] : integrands) {
    std::vector<double> h(kLevelsChecked, 0.0), m(kLevelsChecked + 1, 0.0), m2(kLevelsChecked + 1, 0.0);
    for (int s = 0; s < seeds; ++s) {
      BlockDifferences b;
      double sum = 0;
      for (uint32_t i = 0; i < kN; ++i) {
        PixelSampler p(uint64_t(s) * 7919 + 3, 5, 9, i);
        const Vec2 u = p.next_2d(), v = p.next_2d();
        const double x = f(u, v);
        b.add(x);
        sum += x;
        if (std::has_single_bit(i + 1)) {  // the render at i + 1 spp is this prefix
          const int j = std::countr_zero(i + 1);
          m[size_t(j)] += sum / (i + 1) / seeds;
          m2[size_t(j)] += (sum / (i + 1)) * (sum / (i + 1)) / seeds;
        }
      }
      for (int j = 0; j < kLevelsChecked; ++j) h[size_t(j)] += b.h(j) / seeds;
    }
    const auto var = [&](int j) { return (m2[size_t(j)] - m[size_t(j)] * m[size_t(j)]) * seeds / (seeds - 1.0); };
    for (int j = 0; j < kLevelsChecked; ++j) {
      const double drop = var(j) - var(j + 1);
      EXPECT_NEAR(h[size_t(j)] / drop, 1.0, 0.16 * std::sqrt(4096.0 / seeds)) << name << " at block size " << (1 << j);
    }
  }
}

}  // namespace
}  // namespace tessera
