// Ray/triangle tests, including the watertightness test: 10^7 rays from inside closed meshes, most aimed exactly
// at shared edges and vertices, must never escape. A Moller-Trumbore test (kept here only) leaks on the same rays.
#include "core/geometry/bvh.h"
#include "core/geometry/mesh.h"
#include "tests/support/test_scale.h"
#include "core/geometry/triangle.h"

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <map>
#include <optional>
#include <random>

namespace tessera {
namespace {

const Triangle kTri{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};

TEST(Triangle, HitReportsDistanceAndBarycentrics) {
  const Ray r{{0.25f, 0.25f, 1.f}, {0, 0, -1}};
  auto h = intersect_triangle(r, kTri);
  ASSERT_TRUE(h.has_value());
  EXPECT_FLOAT_EQ(h->t, 1.f);
  EXPECT_FLOAT_EQ(h->b0, 0.5f);
  EXPECT_FLOAT_EQ(h->b1, 0.25f);
  EXPECT_FLOAT_EQ(h->b2, 0.25f);
}

TEST(Triangle, TwoSidedAndRespectsExtent) {
  EXPECT_TRUE(intersect_triangle(Ray{{0.2f, 0.2f, -1.f}, {0, 0, 1}}, kTri).has_value());
  EXPECT_FALSE(intersect_triangle(Ray{{0.2f, 0.2f, 1.f}, {0, 0, 1}}, kTri).has_value());  // behind
  EXPECT_FALSE(intersect_triangle(Ray{{0.2f, 0.2f, 1.f}, {0, 0, -1}, 0.5f}, kTri).has_value());  // too short
  EXPECT_FALSE(intersect_triangle(Ray{{0.8f, 0.8f, 1.f}, {0, 0, -1}}, kTri).has_value());  // outside
}

TEST(Triangle, DegenerateTrianglesNeverHit) {
  const Ray r{{0.f, 0.f, 1.f}, {0, 0, -1}};
  EXPECT_FALSE(intersect_triangle(r, Triangle{{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}));        // a point
  EXPECT_FALSE(intersect_triangle(r, Triangle{{-1, 0, 0}, {1, 0, 0}, {0.5f, 0, 0}}));    // a segment
  // A ray lying in the plane of a triangle sees it edge-on: zero determinant, no hit.
  EXPECT_FALSE(intersect_triangle(Ray{{-1.f, 0.2f, 0.f}, {1, 0, 0}}, kTri));
  EXPECT_TRUE(is_degenerate(Triangle{{1, 2, 3}, {1, 2, 3}, {4, 5, 6}}));
  EXPECT_FALSE(is_degenerate(kTri));
}

TEST(Triangle, NonFiniteAndHugeInputsNeverCrashOrReturnNaN) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = kInfinity;
  const float huge = 3e38f;
  const std::vector<Triangle> tris = {
      kTri,
      {{nan, 0, 0}, {1, 0, 0}, {0, 1, 0}},
      {{inf, 0, 0}, {1, 0, 0}, {0, 1, 0}},
      {{-huge, -huge, 0}, {huge, -huge, 0}, {0, huge, 0}},
      {{-huge, -huge, huge}, {huge, -huge, -huge}, {0, huge, 0}},
      {{1e-30f, 0, 0}, {0, 1e-30f, 0}, {0, 0, 0}},
  };
  const std::vector<Ray> rays = {
      {{0.2f, 0.2f, 1.f}, {0, 0, -1}},       {{nan, 0, 1}, {0, 0, -1}},
      {{0, 0, 1}, {nan, 0, -1}},             {{0, 0, 1}, {0, 0, -inf}},
      {{0, 0, huge}, {0, 0, -1}},            {{0, 0, 1}, {0, 0, -1e-30f}},
      {{0, 0, 1}, {0, 0, 0}},                {{0.1f, 0.1f, 1}, {0, 0, -1}, nan},
      {{0.1f, 0.1f, 1e30f}, {0, 0, -huge}},
  };
  for (const auto& t : tris)
    for (const auto& r : rays) {
      auto h = intersect_triangle(r, t);
      if (h) {
        EXPECT_TRUE(std::isfinite(h->t) && h->t > 0.f);
        EXPECT_TRUE(std::isfinite(h->b0) && std::isfinite(h->b1) && std::isfinite(h->b2));
      }
    }
  // The huge but valid triangle is still hit by an ordinary ray.
  EXPECT_TRUE(intersect_triangle(rays[0], tris[3]).has_value());
}

TEST(Triangle, SharedEdgeIsHitExactlyOnceOrTwiceNeverZero) {
  // Two triangles sharing the diagonal of a unit square; rays through points of the diagonal hit at least one.
  const Triangle a{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}}, b{{0, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < 100000; ++i) {
    const float s = u(rng);
    const Vec3 target(s, s, 0.f);
    const Vec3 o(u(rng) * 3 - 1, u(rng) * 3 - 1, 0.5f + u(rng));
    const Ray r{o, target - o};
    ASSERT_TRUE(intersect_triangle(r, a) || intersect_triangle(r, b)) << "crack at s=" << s;
  }
}

// --- Watertightness over closed meshes --------------------------------------------------------------------

// A ray aimed at a shared feature of a convex closed mesh, with the triangles that share that feature.
struct AimedRay {
  Ray ray;
  uint32_t feature;  // index into the mesh's feature list
};

struct MeshFeatures {
  std::vector<std::vector<uint32_t>> vertex_faces;      // faces around each vertex
  std::vector<std::pair<uint32_t, uint32_t>> edges;     // unique edges
  std::vector<std::vector<uint32_t>> edge_faces;        // faces sharing each edge
};

MeshFeatures features(const TriangleMesh& m) {
  MeshFeatures f;
  f.vertex_faces.resize(m.p.size());
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> edge_index;
  for (uint32_t i = 0; i < m.faces.size(); ++i) {
    const uint32_t v[3] = {m.faces[i].x, m.faces[i].y, m.faces[i].z};
    for (int k = 0; k < 3; ++k) {
      f.vertex_faces[v[k]].push_back(i);
      const auto key = std::minmax(v[k], v[(k + 1) % 3]);
      auto [it, fresh] = edge_index.emplace(key, uint32_t(f.edges.size()));
      if (fresh) {
        f.edges.push_back(key);
        f.edge_faces.emplace_back();
      }
      f.edge_faces[it->second].push_back(i);
    }
  }
  return f;
}

// Non-watertight reference: Moller-Trumbore, the common textbook test. Test-only.
std::optional<float> moller_trumbore(const Ray& r, const Triangle& t) {
  const Vec3 e1 = t.p1 - t.p0, e2 = t.p2 - t.p0;
  const Vec3 pv = glm::cross(r.d, e2);
  const float det = glm::dot(e1, pv);
  if (det == 0.f) return std::nullopt;
  const float inv = 1.f / det;
  const Vec3 tv = r.o - t.p0;
  const float u = glm::dot(tv, pv) * inv;
  if (u < 0.f || u > 1.f) return std::nullopt;
  const Vec3 qv = glm::cross(tv, e1);
  const float v = glm::dot(r.d, qv) * inv;
  if (v < 0.f || u + v > 1.f) return std::nullopt;
  const float tt = glm::dot(e2, qv) * inv;
  if (!(tt > 0.f)) return std::nullopt;
  return tt;
}

struct LeakCounts {
  size_t rays = 0;
  size_t watertight_escapes = 0;  // through the BVH, closest hit
  size_t watertight_local_misses = 0;  // against the triangles sharing the aimed-at feature
  size_t moller_local_misses = 0;
  LeakCounts operator+(const LeakCounts& o) const {
    return {rays + o.rays, watertight_escapes + o.watertight_escapes,
            watertight_local_misses + o.watertight_local_misses, moller_local_misses + o.moller_local_misses};
  }
};

// Shoots n rays from random interior points: 40% at shared vertices, 40% at points on shared edges, 20% in
// random directions. For a convex mesh a ray from inside crosses the surface exactly once, at the aimed point,
// so missing every triangle around that point means the ray escaped through a crack.
LeakCounts shoot(const TriangleMesh& mesh, const Vec3& inner_lo, const Vec3& inner_hi, size_t n, uint32_t seed) {
  const std::vector<Triangle> tris = mesh.triangles();
  const Bvh bvh = Bvh::build(tris, {});
  const MeshFeatures f = features(mesh);
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 1 << 14), LeakCounts{},
      [&](const tbb::blocked_range<size_t>& range, LeakCounts acc) {
        std::mt19937 rng(seed ^ uint32_t(range.begin() * 2654435761u));
        std::uniform_real_distribution<float> u(0.f, 1.f);
        for (size_t i = range.begin(); i != range.end(); ++i) {
          const Vec3 o = inner_lo + Vec3(u(rng), u(rng), u(rng)) * (inner_hi - inner_lo);
          const float kind = u(rng);
          const std::vector<uint32_t>* local = nullptr;
          Vec3 target;
          if (kind < 0.4f) {
            const uint32_t v = std::min<uint32_t>(uint32_t(u(rng) * mesh.p.size()), uint32_t(mesh.p.size() - 1));
            target = mesh.p[v];
            local = &f.vertex_faces[v];
          } else if (kind < 0.8f) {
            const uint32_t e = std::min<uint32_t>(uint32_t(u(rng) * f.edges.size()), uint32_t(f.edges.size() - 1));
            // Away from the endpoints, so that the rounded target lies in a triangle sharing the edge (next to
            // a vertex it may round into another triangle of that vertex's fan).
            const float s = 0.01f + 0.98f * u(rng);
            target = (1.f - s) * mesh.p[f.edges[e].first] + s * mesh.p[f.edges[e].second];
            local = &f.edge_faces[e];
          } else {
            const float z = 1.f - 2.f * u(rng), phi = 2.f * kPi * u(rng), rr = std::sqrt(std::max(0.f, 1 - z * z));
            target = o + Vec3(rr * std::cos(phi), rr * std::sin(phi), z);
          }
          const Ray ray{o, target - o};
          ++acc.rays;
          if (!bvh.intersect(ray)) ++acc.watertight_escapes;
          if (local) {
            bool wt = false, mt = false;
            const WatertightRay wr(ray);
            for (uint32_t fi : *local) {
              wt = wt || intersect_triangle(wr, kInfinity, tris[fi].p0, tris[fi].p1, tris[fi].p2).has_value();
              mt = mt || moller_trumbore(ray, tris[fi]).has_value();
            }
            acc.watertight_local_misses += !wt;
            acc.moller_local_misses += !mt;
          }
        }
        return acc;
      },
      [](const LeakCounts& a, const LeakCounts& b) { return a + b; });
}

// 10^7 rays in all over the three meshes (the main build's count; sanitizer builds run a fraction).
constexpr size_t kRaysPerMesh = 3'400'000;

TEST(Watertight, IcosphereNoEscapes) {
  const TriangleMesh m = make_icosphere({0.3f, -0.2f, 0.1f}, 1.f, 6);  // 81920 triangles
  const LeakCounts c = shoot(m, Vec3(-0.2f), Vec3(0.2f), testing::scaled(kRaysPerMesh), 1);
  EXPECT_EQ(c.watertight_escapes, 0u) << "of " << c.rays;
  EXPECT_EQ(c.watertight_local_misses, 0u);
  EXPECT_GT(c.moller_local_misses, 0u) << "Moller-Trumbore should leak on rays aimed at shared edges";
  RecordProperty("moller_trumbore_leaks", std::to_string(c.moller_local_misses));
  std::printf("icosphere: %zu rays, watertight escapes %zu, Moller-Trumbore leaks %zu\n", c.rays,
              c.watertight_escapes, c.moller_local_misses);
}

TEST(Watertight, TessellatedBoxNoEscapes) {
  const TriangleMesh m = make_box_grid({-1.f, -0.5f, -2.f}, {1.3f, 0.7f, 0.9f}, 100);  // 120000 triangles
  const LeakCounts c = shoot(m, Vec3(-0.9f, -0.4f, -1.9f), Vec3(1.2f, 0.6f, 0.8f), testing::scaled(kRaysPerMesh), 2);
  EXPECT_EQ(c.watertight_escapes, 0u) << "of " << c.rays;
  EXPECT_EQ(c.watertight_local_misses, 0u);
  EXPECT_GT(c.moller_local_misses, 0u);
  std::printf("box: %zu rays, watertight escapes %zu, Moller-Trumbore leaks %zu\n", c.rays, c.watertight_escapes,
              c.moller_local_misses);
}

TEST(Watertight, NeedleCylinderNoEscapes) {
  const TriangleMesh m = make_needle_cylinder({0.1f, -1.f, 0.2f}, 0.5f, 2.f, 20000);  // 80000 needles
  const LeakCounts c = shoot(m, Vec3(-0.15f, -0.9f, -0.05f), Vec3(0.35f, 0.9f, 0.45f),
                             testing::scaled(kRaysPerMesh - 200'000), 3);
  EXPECT_EQ(c.watertight_escapes, 0u) << "of " << c.rays;
  EXPECT_EQ(c.watertight_local_misses, 0u);
  EXPECT_GT(c.moller_local_misses, 0u);
  std::printf("needles: %zu rays, watertight escapes %zu, Moller-Trumbore leaks %zu\n", c.rays,
              c.watertight_escapes, c.moller_local_misses);
}

}  // namespace
}  // namespace tessera
