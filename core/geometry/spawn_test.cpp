// Self-intersection tests: rays spawned from surfaces 1e5 units from the origin never re-hit their surface.
#include "core/geometry/bvh.h"
#include "core/geometry/mesh.h"
#include "core/geometry/spawn.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>

#include <random>

namespace tessera {
namespace {

Vec3 random_direction(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const float z = 1.f - 2.f * u(rng), phi = 2.f * kPi * u(rng), r = std::sqrt(std::max(0.f, 1.f - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

struct FarScene {
  std::vector<Triangle> tris;
  std::vector<Sphere> spheres;
  Bvh bvh;
};

// A tessellated sphere, an analytic sphere and a large two-triangle plane, all about 1e5 from the origin.
FarScene far_scene(const Vec3& offset) {
  FarScene s;
  const TriangleMesh m = make_icosphere(offset + Vec3(0, 0, 0), 1.f, 4);
  s.tris = m.triangles();
  const Vec3 a = offset + Vec3(-50, -3, -50), b = offset + Vec3(50, -3, -50), c = offset + Vec3(50, -3, 50),
             d = offset + Vec3(-50, -3, 50);
  s.tris.push_back({a, b, c});
  s.tris.push_back({a, c, d});
  s.spheres.push_back({offset + Vec3(4, 0, 0), 1.5f});
  s.bvh = Bvh::build(s.tris, s.spheres);
  return s;
}

SurfacePoint surface_point(const FarScene& s, const Ray& r, const Hit& h) {
  if (h.prim < s.bvh.triangle_count()) return triangle_surface_point(s.tris[h.prim], 1.f - h.b1 - h.b2, h.b1, h.b2);
  return sphere_surface_point(s.spheres[h.prim - s.bvh.triangle_count()], r, h.t);
}

struct Counts {
  size_t spawned = 0, self_hits = 0, naive_self_hits = 0;
};

// Finds surface points by shooting at the scene, then spawns rays from them into the hemisphere facing away
// from the surface (nothing convex can be re-hit there) and, for the analytic sphere, into it (the far side must
// be hit at a distance of the order of the radius, not at ~0).
Counts run(const Vec3& offset, size_t n, uint32_t seed) {
  const FarScene s = far_scene(offset);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Counts c;
  for (size_t i = 0; i < n; ++i) {
    const Vec3 o = offset + Vec3(u(rng) * 10, 5 + u(rng) * 3, u(rng) * 10);
    const Vec3 target = offset + Vec3(u(rng) * 5, u(rng) * 2 - 1, u(rng) * 2);
    const Ray r{o, target - o};
    auto h = s.bvh.intersect(r);
    if (!h) continue;
    const SurfacePoint sp = surface_point(s, r, *h);
    Vec3 n = sp.n;
    if (glm::dot(n, r.d) > 0.f) n = -n;  // the side the ray came from
    for (int k = 0; k < 8; ++k) {
      Vec3 w = random_direction(rng);
      if (glm::dot(w, n) < 0.f) w = -w;
      ++c.spawned;
      const Ray out = spawn_ray(sp, w);
      if (auto h2 = s.bvh.intersect(out); h2 && h2->prim == h->prim) ++c.self_hits;
      // Control: the same ray from the unoffset point. It must be able to fail, or the test proves nothing.
      if (auto h3 = s.bvh.intersect(Ray{sp.p, w}); h3 && h3->prim == h->prim) ++c.naive_self_hits;
      // Into the analytic sphere: the far side, at a distance of the order of its radius.
      if (h->prim >= s.bvh.triangle_count()) {
        const Ray in = spawn_ray(sp, -w);
        auto h4 = s.bvh.intersect(in);
        ++c.spawned;
        if (!h4 || h4->t * glm::length(in.d) < 1e-3f) ++c.self_hits;
      }
    }
  }
  return c;
}

TEST(Spawn, NoSelfIntersectionFarFromOrigin) {
  const Counts c = run(Vec3(1e5f, 1e5f, -1e5f), testing::scaled(40000), 5);
  EXPECT_GT(c.spawned, testing::scaled(40000));
  EXPECT_EQ(c.self_hits, 0u) << "of " << c.spawned;
  EXPECT_GT(c.naive_self_hits, c.spawned / 100) << "unoffset origins should self-intersect at 1e5";
  std::printf("at 1e5: %zu spawned rays, %zu self hits (unoffset control: %zu)\n", c.spawned, c.self_hits,
              c.naive_self_hits);
}

TEST(Spawn, NoSelfIntersectionNearOrigin) {
  const Counts c = run(Vec3(0.f), testing::scaled(20000), 6);
  EXPECT_EQ(c.self_hits, 0u) << "of " << c.spawned;
}

TEST(Spawn, NoSelfIntersectionOnLargePlaneThroughOrigin) {
  // A 100 x 100 plane at y = 0 has exact y coordinates, so the interpolation error along its normal is zero; shallow
  // rays leaving it must still clear it (the ray/triangle test's rounding scales with the triangle's extent).
  for (float y : {0.f, 1e-3f}) {
    const Vec3 a(-50, y, -50), b(50, y, -50), c(50, y, 50), d(-50, y, 50);
    const std::vector<Triangle> tris{{a, b, c}, {a, c, d}};
    const Bvh bvh = Bvh::build(tris, {});
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    size_t hits = 0, n = testing::scaled(20000);
    for (size_t i = 0; i < n; ++i) {
      float b1 = u(rng), b2 = u(rng);
      if (b1 + b2 > 1.f) { b1 = 1 - b1; b2 = 1 - b2; }
      const Triangle& tri = tris[i % 2];
      const SurfacePoint sp = triangle_surface_point(tri, 1 - b1 - b2, b1, b2);
      // A point light 0.01 to 2 above the plane, up to 40 away: grazing shadow rays.
      const Vec3 light(u(rng) * 80 - 40, y + 0.01f + 2.f * u(rng), u(rng) * 80 - 40);
      hits += bvh.occluded(spawn_ray_to(sp, light));
      Vec3 w = random_direction(rng);
      if (w.y < 0.f) w.y = -w.y;
      hits += bvh.occluded(spawn_ray(sp, w));
    }
    EXPECT_EQ(hits, 0u) << "plane at y = " << y << ", " << 2 * n << " rays";
  }
}

TEST(Spawn, ShadowRayBetweenSurfacesIgnoresBothEnds) {
  // Two facing triangles far from the origin: a shadow ray between them sees neither.
  const Vec3 off(1e5f, -1e5f, 1e5f);
  const Triangle bottom{off + Vec3(-1, 0, -1), off + Vec3(1, 0, -1), off + Vec3(0, 0, 1)};
  const Triangle top{off + Vec3(-1, 1, -1), off + Vec3(1, 1, -1), off + Vec3(0, 1, 1)};
  const std::vector<Triangle> tris{bottom, top};
  const Bvh bvh = Bvh::build(tris, {});
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < 10000; ++i) {
    float b1 = u(rng), b2 = u(rng);
    if (b1 + b2 > 1.f) { b1 = 1 - b1; b2 = 1 - b2; }
    const SurfacePoint a = triangle_surface_point(bottom, 1 - b1 - b2, b1, b2);
    const SurfacePoint b = triangle_surface_point(top, 1 - b2 - b1, b2, b1);
    ASSERT_FALSE(bvh.occluded(spawn_ray_to(a, b))) << i;
    ASSERT_FALSE(bvh.occluded(spawn_ray_to(b, a))) << i;
  }
}

}  // namespace
}  // namespace tessera
