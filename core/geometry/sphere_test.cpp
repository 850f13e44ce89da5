// Ray/sphere tests: stability for distant and huge spheres, tangents, rays from inside.
#include "core/geometry/sphere.h"

#include <gtest/gtest.h>

namespace tessera {
namespace {

TEST(Sphere, BasicHitsAndMisses) {
  const Sphere s{{0, 0, 0}, 1.f};
  auto t = intersect_sphere(s, Ray{{0, 0, 5}, {0, 0, -1}}, kInfinity);
  ASSERT_TRUE(t);
  EXPECT_FLOAT_EQ(*t, 4.f);
  EXPECT_FALSE(intersect_sphere(s, Ray{{0, 2, 5}, {0, 0, -1}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(s, Ray{{0, 0, 5}, {0, 0, 1}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(s, Ray{{0, 0, 5}, {0, 0, -1}}, 3.f));
  auto inside = intersect_sphere(s, Ray{{0, 0, 0}, {1, 0, 0}}, kInfinity);  // from the centre: far root
  ASSERT_TRUE(inside);
  EXPECT_FLOAT_EQ(*inside, 1.f);
}

TEST(Sphere, TangentRaysHitAndNearTangentMiss) {
  const Sphere s{{0, 0, 0}, 1.f};
  auto t = intersect_sphere(s, Ray{{-5, 1, 0}, {1, 0, 0}}, kInfinity);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, 5.f, 1e-3f);
  EXPECT_FALSE(intersect_sphere(s, Ray{{-5, next_float_up(1.f) + 1e-6f, 0}, {1, 0, 0}}, kInfinity));
}

TEST(Sphere, DistantSmallSphereKeepsPrecision) {
  // The textbook b^2 - 4ac loses every digit here: |o-c|^2 = 1e16 against r^2 = 1e-2.
  const Sphere s{{0, 0, 0}, 0.1f};
  for (float off : {0.f, 0.05f, 0.09f, 0.0999f}) {
    auto t = intersect_sphere(s, Ray{{off, 0, 1e8f}, {0, 0, -1}}, kInfinity);
    ASSERT_TRUE(t) << off;
    const double exact = 1e8 - std::sqrt(0.1 * 0.1 - double(off) * off);
    EXPECT_NEAR(*t, exact, 1e8 * 1e-7) << off;
  }
  EXPECT_FALSE(intersect_sphere(s, Ray{{0.1001f, 0, 1e8f}, {0, 0, -1}}, kInfinity));
}

TEST(Sphere, HugeSphereNearSurface) {
  // A planet-sized sphere seen from just above its surface: the near root must be accurate, not 0 or garbage.
  const float R = 6.4e6f;
  const Sphere s{{0, -R, 0}, R};
  auto t = intersect_sphere(s, Ray{{0, 10.f, 0}, {0, -1, 0}}, kInfinity);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, 10.f, 1.f);  // float spacing of the centre's coordinate at 6.4e6 is 0.5
  auto up = intersect_sphere(s, Ray{{0, 10.f, 0}, {0, 1, 0}}, kInfinity);
  EXPECT_FALSE(up);
}

TEST(Sphere, DegenerateAndNonFiniteInputs) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(intersect_sphere(Sphere{{0, 0, 0}, 0.f}, Ray{{0, 0, 5}, {0, 0, -1}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(Sphere{{0, 0, 0}, -1.f}, Ray{{0, 0, 5}, {0, 0, -1}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(Sphere{{0, 0, 0}, nan}, Ray{{0, 0, 5}, {0, 0, -1}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(Sphere{{nan, 0, 0}, 1}, Ray{{0, 0, 5}, {0, 0, -1}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(Sphere{{0, 0, 0}, 1}, Ray{{0, 0, 5}, {0, 0, 0}}, kInfinity));
  EXPECT_FALSE(intersect_sphere(Sphere{{0, 0, 0}, 1}, Ray{{0, 0, 5}, {nan, 0, -1}}, kInfinity));
  auto t = intersect_sphere(Sphere{{0, 0, 0}, 3e38f}, Ray{{0, 0, 0}, {0, 0, 1}}, kInfinity);
  if (t) {
    EXPECT_TRUE(std::isfinite(*t));
  }
}

}  // namespace
}  // namespace tessera
