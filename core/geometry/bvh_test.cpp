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
      ASSERT_EQ(expect->prim, got->prim) << "ray " << i;  // the lowest id of those at that distance
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

// A closed box of 12 triangles (the walls) around two smaller boxes and a light, as in the Cornell box: a tiny
// scene, built as one node over grouped leaves.
std::vector<Triangle> room() {
  std::vector<Triangle> tris = make_box_grid({-1.f, 0.f, -1.f}, {1.f, 2.f, 1.f}, 1).triangles();
  for (const Triangle& t : make_box_grid({-0.7f, 0.f, -0.6f}, {-0.1f, 1.2f, 0.f}, 1).triangles()) tris.push_back(t);
  for (const Triangle& t : make_box_grid({0.15f, 0.f, 0.1f}, {0.65f, 0.6f, 0.6f}, 1).triangles()) tris.push_back(t);
  tris.push_back({{-0.25f, 1.99f, -0.2f}, {0.25f, 1.99f, -0.2f}, {0.25f, 1.99f, 0.2f}});  // the light
  tris.push_back({{-0.25f, 1.99f, -0.2f}, {0.25f, 1.99f, 0.2f}, {-0.25f, 1.99f, 0.2f}});
  return tris;
}

TEST(Bvh, TinySceneGivesTheSameHitsAsBruteForceInARoom) {
  const Soup s{room(), {}};
  Bvh tiny = Bvh::build(s.tris, {});
  const Bvh median = Bvh::build(s.tris, {}, BvhOptions{SplitMethod::kMedian});  // the binary build's tree
  EXPECT_EQ(tiny.stats().nodes, 1u + tiny.stats().leaves);  // one node over its leaves
  EXPECT_LE(tiny.stats().leaves, 8u);
  for (SimdPath path : supported_simd_paths()) {
    SCOPED_TRACE(std::string(kSimdPathNames[size_t(path)]));
    tiny.set_simd_path(path);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    size_t hits = 0;
    for (size_t i = 0; i < testing::scaled(40000); ++i) {
      // From inside the room, from outside and from vertices; toward random points, the edges where walls meet and
      // the quads' diagonals (where two triangles meet at the same distance).
      Vec3 o = Vec3(u(rng), u(rng) + 1.f, u(rng)) * 0.98f;
      if (i % 5 == 1) o = Vec3(u(rng), u(rng) + 1.f, u(rng)) * 3.f;
      const Triangle& t = s.tris[(i * 13) % s.tris.size()];
      if (i % 7 == 3) o = t.p1;
      const float f = 0.5f * (u(rng) + 1.f);
      Vec3 target = Vec3(u(rng), u(rng) + 1.f, u(rng)) * 1.5f;
      if (i % 3 == 1) target = t.p0 + f * (t.p1 - t.p0);
      if (i % 3 == 2) target = t.p0 + f * (t.p2 - t.p0);
      Ray r{o, target - o};
      if (i % 4 == 2) r.tmax = 0.5f + (u(rng) + 1.f);
      const auto expect = brute_force(s, r);
      const auto got = tiny.intersect(r), other = median.intersect(r);
      ASSERT_EQ(expect.has_value(), got.has_value()) << "ray " << i;
      ASSERT_EQ(tiny.occluded(r), expect.has_value()) << "ray " << i;
      if (!expect) continue;
      ++hits;
      ASSERT_EQ(std::bit_cast<uint32_t>(expect->t), std::bit_cast<uint32_t>(got->t)) << "ray " << i;
      ASSERT_EQ(expect->prim, got->prim) << "ray " << i;
      ASSERT_TRUE(other);  // and bitwise the hit of another tree
      ASSERT_EQ(std::bit_cast<uint32_t>(other->t), std::bit_cast<uint32_t>(got->t)) << "ray " << i;
      ASSERT_EQ(other->prim, got->prim) << "ray " << i;
      ASSERT_EQ(std::bit_cast<uint32_t>(other->b1), std::bit_cast<uint32_t>(got->b1)) << "ray " << i;
      ASSERT_EQ(std::bit_cast<uint32_t>(other->b2), std::bit_cast<uint32_t>(got->b2)) << "ray " << i;
    }
    EXPECT_GT(hits, testing::scaled(40000) / 2);
  }
}

TEST(Bvh, TinyRandomSoupsMatchBruteForce) {
  // Up to 64 primitives: degenerate, huge, tiny and coincident triangles and spheres in a few grouped leaves.
  for (uint32_t seed : {5u, 6u, 7u}) {
    Soup s = random_soup(50, seed);
    ASSERT_LE(s.tris.size() + s.spheres.size(), 64u);
    const Bvh bvh = Bvh::build(s.tris, s.spheres);
    EXPECT_EQ(bvh.stats().nodes, 1u + bvh.stats().leaves);
    compare(s, bvh, testing::scaled(20000), seed * 17);
  }
}

TEST(Bvh, HitsAtTheSameDistanceGoToTheLowestId) {
  // Copies of one triangle among others, at ids that different trees visit in different orders; a ray through the
  // copies meets all of them at the same t and must report the lowest id, whatever the tree and the SimdPath.
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<Triangle> tris;
  while (tris.size() < 300) {  // small triangles away from the ray
    const Vec3 c = Vec3(u(rng), u(rng), u(rng)) * 10.f;
    if (std::abs(c.x) < 2.f && std::abs(c.y) < 2.f) continue;
    tris.push_back({c, c + Vec3(u(rng), u(rng), u(rng)) * 0.5f, c + Vec3(u(rng), u(rng), u(rng)) * 0.5f});
  }
  const Triangle copy{{-0.5f, -0.5f, 0.3f}, {0.6f, -0.4f, 0.35f}, {0.f, 0.7f, 0.25f}};
  uint32_t lowest = 0xffffffffu;
  for (uint32_t i = 17; i < 300; i += 37) {
    tris[i] = copy;
    lowest = std::min(lowest, i);
  }
  const Ray r{{0.05f, 0.02f, 5.f}, {0.f, 0.f, -1.f}};
  for (int max_leaf : {1, 2, 8, 64}) {
    for (SplitMethod m : {SplitMethod::kSah, SplitMethod::kMedian}) {
      BvhOptions opt;
      opt.split = m;
      opt.max_leaf_prims = max_leaf;
      Bvh bvh = Bvh::build(tris, {}, opt);
      for (SimdPath p : supported_simd_paths()) {
        bvh.set_simd_path(p);
        const auto h = bvh.intersect(r);
        ASSERT_TRUE(h);
        EXPECT_EQ(h->prim, lowest) << "max_leaf " << max_leaf << " path " << kSimdPathNames[size_t(p)];
      }
    }
  }
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
