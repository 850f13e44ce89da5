// portable_sin / portable_cos against long-double references: within one float ulp over the angles the sampling code
// uses and far beyond, exact at zero, odd and even.
#include "core/trig.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>

namespace tessera {
namespace {

// Distance in float ulps between f and the exact value y.
double ulps(float f, long double y) {
  const float yf = float(y);
  const double ulp = double(std::nextafter(std::abs(yf), INFINITY) - std::abs(yf));
  return double(std::abs((long double)f - y)) / (ulp > 0 ? ulp : 1e-45);
}

TEST(PortableTrig, WithinOneFloatUlp) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> near(-7.f, 7.f), far(-1e5f, 1e5f);
  double worst = 0;
  for (int i = 0; i < 400000; ++i) {
    const float x = i % 4 == 3 ? far(rng) : near(rng);
    worst = std::max({worst, ulps(portable_sin(x), std::sin((long double)x)), ulps(portable_cos(x), std::cos((long double)x))});
  }
  std::printf("worst error: %.3f ulp\n", worst);
  EXPECT_LE(worst, 1.0);
}

TEST(PortableTrig, SpecialValuesAndSymmetry) {
  EXPECT_EQ(0.f, portable_sin(0.f));
  EXPECT_EQ(1.f, portable_cos(0.f));
  for (float x : {1e-20f, 0.3f, 1.f, 2.5f, 3.14159265f, 6.2831853f, 100.f}) {
    EXPECT_EQ(-portable_sin(x), portable_sin(-x)) << x;
    EXPECT_EQ(portable_cos(x), portable_cos(-x)) << x;
  }
  EXPECT_EQ(1e-20f, portable_sin(1e-20f));
}

// portable_sincos is bitwise the pair of portable_sin and portable_cos, in every quadrant and far out.
TEST(PortableTrig, SinCosIsBitwiseTheSeparateFunctions) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> near(-7.f, 7.f), far(-1e6f, 1e6f);
  for (int i = 0; i < 200000; ++i) {
    const float x = i % 4 == 3 ? far(rng) : near(rng);
    const SinCos sc = portable_sincos(x);
    ASSERT_EQ(std::bit_cast<uint32_t>(sc.sin), std::bit_cast<uint32_t>(portable_sin(x))) << x;
    ASSERT_EQ(std::bit_cast<uint32_t>(sc.cos), std::bit_cast<uint32_t>(portable_cos(x))) << x;
  }
  for (const float x : {0.f, -0.f, 1e-30f, 3.4e38f, -3.4e38f, 2.f * 3.14159265f, 4.5e15f})
    EXPECT_EQ(std::bit_cast<uint32_t>(portable_sincos(x).sin), std::bit_cast<uint32_t>(portable_sin(x))) << x;
}

}  // namespace
}  // namespace tessera
