// Ray/box tests: axis-parallel rays, origins on slab planes, zero, tiny and infinite direction components.
#include "core/geometry/bounds.h"

#include <gtest/gtest.h>

#include <random>

namespace tessera {
namespace {

const Bounds3 kBox{{1, 0, 0}, {2, 1, 1}};

bool fast_hit(const Bounds3& b, const Ray& r) {
  float t;
  return slab_test(b, BoxRay(r), r.tmax, &t);
}

TEST(Bounds, AxisParallelRays) {
  auto h = intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {1, 0, 0}});
  ASSERT_TRUE(h);
  EXPECT_FLOAT_EQ(h->t0, 1.f);
  EXPECT_GE(h->t1, 2.f);
  EXPECT_FALSE(intersect_box(kBox, Ray{{0, 1.5f, 0.5f}, {1, 0, 0}}));
  EXPECT_FALSE(intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {-1, 0, 0}}));
  EXPECT_FALSE(intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {1, 0, 0}, 0.5f}));  // ends before the box
  EXPECT_TRUE(fast_hit(kBox, Ray{{0, 0.5f, 0.5f}, {1, 0, 0}}));
  EXPECT_FALSE(fast_hit(kBox, Ray{{0, 1.5f, 0.5f}, {1, 0, 0}}));
}

TEST(Bounds, OriginOnSlabPlaneWithZeroDirection) {
  // The ray runs inside the box's top face plane (y = 1) with d.y = 0: 0 * inf would be NaN. A closed box is hit.
  for (float dy : {0.f, -0.f}) {
    const Ray on_plane{{0, 1.f, 0.5f}, {1, dy, 0}};
    EXPECT_TRUE(intersect_box(kBox, on_plane)) << dy;
    EXPECT_TRUE(fast_hit(kBox, on_plane)) << dy;
    const Ray on_low_plane{{0, 0.f, 0.5f}, {1, dy, 0}};
    EXPECT_TRUE(intersect_box(kBox, on_low_plane));
    EXPECT_TRUE(fast_hit(kBox, on_low_plane));
    // One ulp outside the plane: parallel and outside, a miss for both tests.
    const Ray just_out{{0, next_float_up(1.f), 0.5f}, {1, dy, 0}};
    EXPECT_FALSE(intersect_box(kBox, just_out));
    EXPECT_FALSE(fast_hit(kBox, just_out));
  }
  // Origin on an entry plane, moving in: entry at t = 0.
  auto h = intersect_box(kBox, Ray{{1, 0.5f, 0.5f}, {1, 0, 0}});
  ASSERT_TRUE(h);
  EXPECT_EQ(h->t0, 0.f);
  // Origin on the exit plane moving out touches the closed box at t = 0 only.
  EXPECT_TRUE(intersect_box(kBox, Ray{{2, 0.5f, 0.5f}, {1, 0, 0}}));
  // On a corner edge, direction with two zero components.
  EXPECT_TRUE(fast_hit(kBox, Ray{{0, 1, 1}, {1, 0, 0}}));
  EXPECT_TRUE(intersect_box(kBox, Ray{{0, 1, 1}, {1, 0, 0}}));
}

TEST(Bounds, TinyAndInfiniteDirectionComponents) {
  // Tiny components (normal and subnormal, whose reciprocal overflows) behave like zero where they should.
  for (float tiny : {1e-30f, 1e-40f, -1e-40f, std::numeric_limits<float>::denorm_min()}) {
    EXPECT_TRUE(intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {1, tiny, 0}})) << tiny;
    EXPECT_TRUE(fast_hit(kBox, Ray{{0, 0.5f, 0.5f}, {1, tiny, 0}})) << tiny;
    EXPECT_FALSE(intersect_box(kBox, Ray{{0, 1.5f, 0.5f}, {1, tiny, 0}})) << tiny;
    EXPECT_FALSE(fast_hit(kBox, Ray{{0, 1.5f, 0.5f}, {1, tiny, 0}})) << tiny;
  }
  // Infinite or NaN directions are not rays: never a hit, never a crash.
  const float inf = kInfinity, nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {inf, 0, 0}}));
  EXPECT_FALSE(intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {1, nan, 0}}));
  EXPECT_FALSE(intersect_box(kBox, Ray{{0, 0.5f, 0.5f}, {0, 0, 0}}));
  EXPECT_FALSE(intersect_box(kBox, Ray{{nan, 0.5f, 0.5f}, {1, 0, 0}}));
  EXPECT_FALSE(intersect_box(Bounds3{}, Ray{{0, 0.5f, 0.5f}, {1, 0, 0}}));  // empty box
}

TEST(Bounds, FastTestIsConservativeAgainstRobustTest) {
  // Random rays with special components: whenever the robust test reports a hit, the hot-path test must too.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-3.f, 3.f);
  std::uniform_int_distribution<int> pick(0, 5);
  auto special = [&](float v) {
    switch (pick(rng)) {
      case 0: return 0.f;
      case 1: return -0.f;
      case 2: return 1e-38f;
      case 3: return std::round(v);  // lands on slab planes often
      default: return v;
    }
  };
  size_t hits = 0;
  for (int i = 0; i < 200000; ++i) {
    const Bounds3 b{{-1, 0, 1}, {1, 2, 2}};
    const Ray r{{special(u(rng)), special(u(rng)), special(u(rng))}, {special(u(rng)), special(u(rng)), special(u(rng))}};
    if (!r.valid()) continue;
    const bool robust = intersect_box(b, r).has_value();
    hits += robust;
    if (robust) {
      ASSERT_TRUE(fast_hit(b, r)) << "culled a box the ray touches";
    }
  }
  EXPECT_GT(hits, 1000u);
}

TEST(Bounds, ConservativeFarDistanceKeepsGrazingHits) {
  // A ray that grazes a thin box far from the origin: rounding of t1 must not cull it.
  const Bounds3 thin{{1e5f, 1e5f, 1e5f}, {1e5f + 1.f, 1e5f, 1e5f + 1.f}};  // zero thickness in y
  const Vec3 o(0.f, 0.f, 0.f);
  for (int i = 0; i < 1000; ++i) {
    const Vec3 target(1e5f + i / 1000.f, 1e5f, 1e5f + 0.5f);
    const Ray r{o, target - o};
    EXPECT_TRUE(fast_hit(thin, r)) << i;
  }
}

}  // namespace
}  // namespace tessera
