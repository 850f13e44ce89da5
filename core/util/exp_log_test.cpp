// portable_exp / portable_log1p / portable_erf against long-double references over the ranges the microfacet code
// uses and beyond, and their special values.
#include "core/util/exp_log.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace tessera {
namespace {

double rel(double v, long double ref) {
  return ref == 0 ? double(std::abs((long double)v)) : double(std::abs(((long double)v - ref) / ref));
}

TEST(PortableExpLog, ExpWithin1e15) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> wide(-708.0, 709.0), near(-40.0, 5.0);  // normal results
  double worst = 0;
  for (int i = 0; i < 300000; ++i) {
    const double x = i % 2 ? wide(rng) : near(rng);
    worst = std::max(worst, rel(portable_exp(x), std::exp((long double)x)));
  }
  std::printf("worst relative error: %.3g\n", worst);
  EXPECT_LE(worst, 1e-15);
  EXPECT_EQ(1.0, portable_exp(0.0));
  EXPECT_EQ(0.0, portable_exp(-800.0));
  EXPECT_TRUE(std::isinf(portable_exp(710.0)));
  EXPECT_TRUE(std::isnan(portable_exp(NAN)));
}

TEST(PortableExpLog, Log1pWithin1e15) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  std::uniform_real_distribution<double> expo(-60.0, 60.0);
  double worst = 0;
  for (int i = 0; i < 300000; ++i) {
    // -u for a float u in [0, 1) (the microfacet sampling's use), and arguments of every size.
    const double x = i % 2 ? -double(unit(rng)) : std::exp2(expo(rng)) * (i % 4 == 0 ? -1e-30 : 1.0);
    if (!(x > -1.0)) continue;
    worst = std::max(worst, rel(portable_log1p(x), std::log1p((long double)x)));
  }
  std::printf("worst relative error: %.3g\n", worst);
  EXPECT_LE(worst, 1e-15);
  EXPECT_EQ(0.0, portable_log1p(0.0));
  EXPECT_EQ(1e-300, portable_log1p(1e-300));
  EXPECT_TRUE(std::isinf(portable_log1p(-1.0)) && portable_log1p(-1.0) < 0);
  EXPECT_TRUE(std::isnan(portable_log1p(-1.5)));
}

TEST(PortableExpLog, ErfWithin1e14) {
  double worst = 0;
  for (int i = -100000; i <= 100000; ++i) {
    const double x = double(i) * 1e-4;  // [-10, 10], across the series / continued-fraction switch at 3
    worst = std::max(worst, rel(portable_erf(x), std::erf((long double)x)));
  }
  for (const double x : {1e-300, 1e-10, 2.9999999999, 3.0, 5.9999999, 6.0})
    worst = std::max(worst, rel(portable_erf(x), std::erf((long double)x)));
  std::printf("worst relative error: %.3g\n", worst);
  EXPECT_LE(worst, 1e-14);
  EXPECT_EQ(0.0, portable_erf(0.0));
  EXPECT_EQ(-portable_erf(0.7), portable_erf(-0.7));
  EXPECT_EQ(1.0, portable_erf(50.0));
  EXPECT_TRUE(std::isnan(portable_erf(NAN)));
}

}  // namespace
}  // namespace tessera
