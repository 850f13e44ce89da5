// portable_sin / portable_cos / portable_atan2 / portable_acos against long-double references: within one float ulp
// over the arguments the renderer uses and far beyond, with the special values and symmetries of the C functions.
#include "core/util/trig.h"

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

TEST(PortableTrig, TanWithinOneFloatUlp) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> fov(0.f, 1.5707f), any(-100.f, 100.f);
  double worst = 0;
  for (int i = 0; i < 400000; ++i) {
    const float x = i % 2 ? fov(rng) : any(rng);  // half a field of view (the camera's use), and any angle
    worst = std::max(worst, ulps(portable_tan(x), std::tan((long double)x)));
  }
  std::printf("worst error: %.3f ulp\n", worst);
  EXPECT_LE(worst, 1.0);
  EXPECT_EQ(0.f, portable_tan(0.f));
  EXPECT_EQ(-portable_tan(0.7f), portable_tan(-0.7f));
}

TEST(PortableTrig, Atan2WithinOneFloatUlp) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(-1.f, 1.f), expo(-30.f, 30.f);
  double worst = 0;
  for (int i = 0; i < 400000; ++i) {
    // Directions (the renderer's use) and arguments of any relative size.
    float y = unit(rng), x = unit(rng);
    if (i % 3 == 2) {
      y *= std::exp2(expo(rng));
      x *= std::exp2(expo(rng));
    }
    worst = std::max(worst, ulps(portable_atan2(y, x), std::atan2((long double)y, (long double)x)));
  }
  // Near the axes and the diagonals, where the reductions switch.
  for (const float e : {1e-30f, 1e-7f, 1e-3f, 0.03125f, 0.5f})
    for (const float s : {1.f, -1.f})
      for (const float t : {1.f, -1.f}) {
        const float pts[][2] = {{s * e, t}, {s, t * e}, {s, t * (1.f + e)}, {s * (1.f - e), t}};
        for (const auto& p : pts)
          worst = std::max(worst, ulps(portable_atan2(p[0], p[1]), std::atan2((long double)p[0], (long double)p[1])));
      }
  std::printf("worst error: %.3f ulp\n", worst);
  EXPECT_LE(worst, 1.0);
}

TEST(PortableTrig, AcosWithinOneFloatUlp) {
  double worst = 0;
  for (int i = -1000000; i <= 1000000; ++i) {
    const float x = float(i) / 1e6f;
    worst = std::max(worst, ulps(portable_acos(x), std::acos((long double)x)));
  }
  for (float x = 1.f; x > 0.999f; x = std::nextafter(x, 0.f)) {  // next to 1 and -1: the steepest part
    worst = std::max(worst, ulps(portable_acos(x), std::acos((long double)x)));
    worst = std::max(worst, ulps(portable_acos(-x), std::acos((long double)-x)));
  }
  std::printf("worst error: %.3f ulp\n", worst);
  EXPECT_LE(worst, 1.0);
}

TEST(PortableTrig, Atan2AndAcosSpecialValues) {
  const auto bits = [](float v) { return std::bit_cast<uint32_t>(v); };
  // Signed zeros and the axes, exactly as the C functions give them.
  for (const float z : {0.f, -0.f})
    for (const float v : {0.f, -0.f, 1.f, -1.f, 2.5f, -3e-39f}) {
      EXPECT_EQ(bits(std::atan2(z, v)), bits(portable_atan2(z, v))) << z << " " << v;
      EXPECT_EQ(bits(std::atan2(v, z)), bits(portable_atan2(v, z))) << v << " " << z;
    }
  for (const float y : {INFINITY, -INFINITY, 1.f})
    for (const float x : {INFINITY, -INFINITY, 1.f})
      EXPECT_EQ(bits(std::atan2(y, x)), bits(portable_atan2(y, x))) << y << " " << x;
  EXPECT_TRUE(std::isnan(portable_atan2(NAN, 1.f)));
  EXPECT_EQ(0.f, portable_acos(1.f));
  EXPECT_EQ(bits(std::acos(-1.f)), bits(portable_acos(-1.f)));
  EXPECT_EQ(bits(std::acos(0.f)), bits(portable_acos(0.f)));
  EXPECT_TRUE(std::isnan(portable_acos(1.0000001f)));
  EXPECT_TRUE(std::isnan(portable_acos(NAN)));
}

}  // namespace
}  // namespace tessera
