// BVH against brute force over random triangle soups with degenerate, huge, tiny and coincident triangles.
#include "core/geometry/bvh.h"
#include "core/geometry/mesh.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <bit>
#include <random>

namespace tessera {
namespace {

struct Soup {
  std::vector<Triangle> tris;
  std::vector<Sphere> spheres;
};

Soup random_soup(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  auto point = [&](float scale) { return Vec3(u(rng), u(rng), u(rng)) * scale; };
  Soup s;
  for (size_t i = 0; i < n; ++i) {
    const Vec3 c = point(10.f);
    switch (i % 8) {
      case 0: s.tris.push_back({c, c, c}); break;                                   // a point
      case 1: { const Vec3 d = point(1.f); s.tris.push_back({c, c + d, c + 2.f * d}); break; }  // a segment
      case 2: s.tris.push_back({point(1e4f), point(1e4f), point(1e4f)}); break;     // huge
      case 3: s.tris.push_back({c, c + point(1e-4f), c + point(1e-4f)}); break;     // tiny
      case 4:                                                                        // coincident pair
        s.tris.push_back({c, c + point(2.f), c + point(2.f)});
        s.tris.push_back(s.tris.back());
        break;
      default: s.tris.push_back({c, c + point(2.f), c + point(2.f)}); break;
    }
  }
  for (size_t i = 0; i < n / 50; ++i) s.spheres.push_back({point(10.f), 0.2f + 0.5f * (u(rng) + 1.f)});
  s.spheres.push_back({point(10.f), 0.f});  // radius 0: never hit
  return s;
}

struct BruteHit {
  float t;
  uint32_t prim;
};

std::optional<BruteHit> brute_force(const Soup& s, const Ray& r) {
  std::optional<BruteHit> best;
  float tmax = r.tmax;
  if (!r.valid()) return best;
  const WatertightRay wr(r);
  for (uint32_t i = 0; i < s.tris.size(); ++i)
    if (auto h = intersect_triangle(wr, tmax, s.tris[i].p0, s.tris[i].p1, s.tris[i].p2)) {
      tmax = h->t;
      best = BruteHit{h->t, i};
    }
  for (uint32_t i = 0; i < s.spheres.size(); ++i)
    if (auto t = intersect_sphere(s.spheres[i], r, tmax)) {
      tmax = *t;
      best = BruteHit{*t, uint32_t(s.tris.size() + i)};
    }
  return best;
}

void compare(const Soup& s, const Bvh& bvh, size_t rays, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  size_t hits = 0;
  for (size_t i = 0; i < rays; ++i) {
    Ray r{Vec3(u(rng), u(rng), u(rng)) * 20.f, Vec3(u(rng), u(rng), u(rng))};
    if (i % 4 == 1) r.d[i % 3] = 0.f;                               // axis-parallel components
    if (i % 4 == 2) r.tmax = 5.f + 10.f * (u(rng) + 1.f);           // bounded rays
    if (i % 16 == 3) r.o = s.tris[(i * 7) % s.tris.size()].p0;      // origins on vertices
    const auto expect = brute_force(s, r);
    const auto got = bvh.intersect(r);
    ASSERT_EQ(expect.has_value(), got.has_value()) << "ray " << i;
    if (expect) {
      ++hits;
      ASSERT_EQ(expect->t, got->t) << "ray " << i;  // bitwise: same test, same nearest distance
    }
    ASSERT_EQ(bvh.occluded(r), expect.has_value()) << "ray " << i;
    if (expect) {
      Ray shorter = r;
      shorter.tmax = expect->t;  // open interval: the nearest hit itself is excluded
      ASSERT_FALSE(bvh.occluded(shorter) && !bvh.intersect(shorter)) << "any-hit found what closest-hit did not";
    }
  }
  EXPECT_GT(hits, rays / 10);
}

TEST(Bvh, MatchesBruteForceOnRandomSoups) {
  for (uint32_t seed : {1u, 2u, 3u, 4u}) {
    const Soup s = random_soup(1500, seed);
    const Bvh bvh = Bvh::build(s.tris, s.spheres);
    compare(s, bvh, testing::scaled(25000), seed * 31);
  }
}

TEST(Bvh, MedianSplitMatchesBruteForce) {
  const Soup s = random_soup(1500, 9);
  const Bvh bvh = Bvh::build(s.tris, s.spheres, BvhOptions{SplitMethod::kMedian});
  compare(s, bvh, testing::scaled(10000), 99);
}

TEST(Bvh, ParallelBuildOfLargeInputMatchesBruteForce) {
  // Large enough to take the parallel binning and parallel subtree paths.
  Soup s = random_soup(200000, 5);
  const Bvh bvh = Bvh::build(s.tris, s.spheres);
  const BvhStats st = bvh.stats();
  EXPECT_LE(st.max_depth, Bvh::kMaxDepth);
  EXPECT_GT(st.leaves, 200000u / 8);
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (size_t i = 0; i < testing::scaled(300); ++i) {
    const Ray r{Vec3(u(rng), u(rng), u(rng)) * 20.f, Vec3(u(rng), u(rng), u(rng))};
    const auto expect = brute_force(s, r);
    const auto got = bvh.intersect(r);
    ASSERT_EQ(expect.has_value(), got.has_value());
    if (expect) {
      ASSERT_EQ(expect->t, got->t);
    }
  }
}

TEST(Bvh, LargeBuildIsTheSameOnAnyThreadCount) {
  // Large enough for the parallel partition (chunks partitioned side by side, then misplaced runs swapped): the tree,
  // and with it every hit, must not depend on how many threads built it.
  const Soup s = random_soup(340000, 21);  // about 300k references: the root split is partitioned in parallel
  auto build_on = [&](int threads) {
    tbb::task_arena arena(threads);
    Bvh bvh;
    arena.execute([&] { bvh = Bvh::build(s.tris, s.spheres); });
    return bvh;
  };
  const Bvh one = build_on(1), three = build_on(3);
  const BvhStats a = one.stats(), b = three.stats();
  EXPECT_EQ(a.nodes, b.nodes);
  EXPECT_EQ(a.leaves, b.leaves);
  EXPECT_EQ(a.max_depth, b.max_depth);
  EXPECT_EQ(a.sah_cost, b.sah_cost);
  EXPECT_EQ(one.memory_bytes(), three.memory_bytes());
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  size_t hits = 0;
  for (size_t i = 0; i < testing::scaled(20000); ++i) {
    const Ray r{Vec3(u(rng), u(rng), u(rng)) * 20.f, Vec3(u(rng), u(rng), u(rng))};
    const auto x = one.intersect(r), y = three.intersect(r);
    ASSERT_EQ(x.has_value(), y.has_value()) << "ray " << i;
    if (!x) continue;
    ++hits;
    ASSERT_EQ(std::bit_cast<uint32_t>(x->t), std::bit_cast<uint32_t>(y->t)) << "ray " << i;
    ASSERT_EQ(std::bit_cast<uint32_t>(x->b1), std::bit_cast<uint32_t>(y->b1)) << "ray " << i;
    ASSERT_EQ(std::bit_cast<uint32_t>(x->b2), std::bit_cast<uint32_t>(y->b2)) << "ray " << i;
    ASSERT_EQ(x->prim, y->prim) << "ray " << i;
  }
  EXPECT_GT(hits, testing::scaled(20000) / 10);
  // And the parallel partition put every reference on its side: hits match brute force.
  for (size_t i = 0; i < testing::scaled(100); ++i) {
    const Ray r{Vec3(u(rng), u(rng), u(rng)) * 20.f, Vec3(u(rng), u(rng), u(rng))};
    const auto expect = brute_force(s, r);
    const auto got = three.intersect(r);
    ASSERT_EQ(expect.has_value(), got.has_value()) << "ray " << i;
    if (expect) {
      ASSERT_EQ(expect->t, got->t) << "ray " << i;
    }
  }
}

TEST(Bvh, MultiPacketAndMixedLeavesMatchBruteForce) {
  // Primitives sharing one centroid cannot be split apart, so with a large leaf limit they form one leaf that spans
  // several 4-wide packets and mixes triangles with spheres; a leaf limit of 1 leaves most packet lanes unused.
  // The triangles lie in distinct planes: overlapping coplanar triangles in different leaves can report a hit one
  // rounding step farther than brute force (a box is culled when its computed entry distance rounds above the
  // closest t so far), which this bitwise comparison would flag.
  Soup s = random_soup(400, 12);
  const Vec3 c(1.f, -2.f, 0.5f);
  for (int i = 0; i < 7; ++i) {
    const float a = 0.3f + 0.2f * float(i), b = 0.15f * float(i - 3) * a;
    const Vec3 p[3] = {{-a, -a, -b}, {a, -a, b}, {0.f, a, 0.f}};  // box centred on the origin, tilted by i
    auto rot = [&](const Vec3& v) { return i % 3 == 0 ? v : i % 3 == 1 ? Vec3(v.z, v.x, v.y) : Vec3(v.y, v.z, v.x); };
    s.tris.push_back({c + rot(p[0]), c + rot(p[1]), c + rot(p[2])});
  }
  for (int i = 0; i < 5; ++i) s.spheres.push_back({c, 0.05f + 0.04f * float(i)});
  for (int max_leaf : {1, 16, 64}) {
    BvhOptions opt;
    opt.max_leaf_prims = max_leaf;
    const Bvh bvh = Bvh::build(s.tris, s.spheres, opt);
    compare(s, bvh, testing::scaled(3000), 40u + uint32_t(max_leaf));
    // Rays aimed into the cluster from all sides.
    std::mt19937 rng{uint32_t(max_leaf)};
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    for (size_t i = 0; i < testing::scaled(3000); ++i) {
      const Vec3 o = c + Vec3(u(rng), u(rng), u(rng)) * 5.f;
      const Ray r{o, c + Vec3(u(rng), u(rng), u(rng)) * 0.4f - o};
      const auto expect = brute_force(s, r);
      const auto got = bvh.intersect(r);
      ASSERT_EQ(expect.has_value(), got.has_value()) << "max_leaf " << max_leaf << " ray " << i;
      if (expect) {
        ASSERT_EQ(expect->t, got->t) << "max_leaf " << max_leaf << " ray " << i;
      }
      ASSERT_EQ(bvh.occluded(r), expect.has_value());
    }
  }
}

TEST(Bvh, ManyCoincidentPrimitivesKeepDepthBounded) {
  // 100k copies of one triangle: centroids coincide, no split separates them.
  std::vector<Triangle> tris(100000, Triangle{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  const Bvh bvh = Bvh::build(tris, {});
  EXPECT_LE(bvh.stats().max_depth, Bvh::kMaxDepth);
  auto h = bvh.intersect(Ray{{0.2f, 0.2f, 1}, {0, 0, -1}});
  ASSERT_TRUE(h);
  EXPECT_FLOAT_EQ(h->t, 1.f);
  // A sliver sequence whose SAH splits are maximally unbalanced still stays within the stack bound.
  std::vector<Triangle> chain;
  for (int i = 0; i < 20000; ++i) {
    const float x = std::ldexp(1.f, -(i % 120));
    chain.push_back({{x, 0, 0}, {x, 1, 0}, {x, 0, 1}});
  }
  EXPECT_LE(Bvh::build(chain, {}).stats().max_depth, Bvh::kMaxDepth);
}

TEST(Bvh, EmptyAndInvalid) {
  const Bvh empty = Bvh::build({}, {});
  EXPECT_FALSE(empty.intersect(Ray{{0, 0, 0}, {1, 0, 0}}));
  EXPECT_FALSE(empty.occluded(Ray{{0, 0, 0}, {1, 0, 0}}));
  std::vector<Triangle> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  const Bvh one = Bvh::build(tris, {});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(one.intersect(Ray{{0.2f, 0.2f, nan}, {0, 0, -1}}));
  EXPECT_FALSE(one.occluded(Ray{{0.2f, 0.2f, 1}, {0, 0, 0}}));
  EXPECT_TRUE(one.occluded(Ray{{0.2f, 0.2f, 1}, {0, 0, -1}}));
}

TEST(Bvh, SahBeatsMedianOnAnUnevenScene) {
  // A dense cluster plus a few far triangles: SAH should find a cheaper tree than the object median.
  std::vector<Triangle> tris = make_icosphere({0, 0, 0}, 1.f, 5).triangles();
  for (int i = 0; i < 200; ++i) tris.push_back({{100.f + i, 0, 0}, {100.5f + i, 0, 0}, {100.f + i, 0.5f, 0}});
  const double sah = Bvh::build(tris, {}).stats().sah_cost;
  const double median = Bvh::build(tris, {}, BvhOptions{SplitMethod::kMedian}).stats().sah_cost;
  EXPECT_LT(sah, median);
  std::printf("SAH cost: binned SAH %.2f, median %.2f\n", sah, median);
}

}  // namespace
}  // namespace tessera
