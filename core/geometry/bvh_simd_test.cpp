// Every SimdPath this CPU runs returns bitwise the same hits as the SSE2 path (same t, primitive and barycentrics,
// same occlusion answers) on random, edge-aimed, vertex-aimed, axis-parallel and grazing rays, and renders bitwise
// the same pixels. Paths the CPU cannot run are skipped (and say so).
#include "core/geometry/bvh.h"
#include "core/geometry/mesh.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

namespace tessera {
namespace {

// What a query returned, as bits.
struct Answer {
  bool hit = false;
  uint32_t t = 0, b1 = 0, b2 = 0, prim = 0;
  bool occluded = false;
  bool operator==(const Answer&) const = default;
};

Answer ask(const Bvh& bvh, const Ray& r) {
  Answer a;
  if (const auto h = bvh.intersect(r)) {
    a.hit = true;
    a.t = std::bit_cast<uint32_t>(h->t);
    a.b1 = std::bit_cast<uint32_t>(h->b1);
    a.b2 = std::bit_cast<uint32_t>(h->b2);
    a.prim = h->prim;
  }
  a.occluded = bvh.occluded(r);
  return a;
}

std::string describe(const Ray& r) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "o (%a, %a, %a) d (%a, %a, %a) tmax %a", r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z,
                r.tmax);
  return buf;
}

// Traces every ray on every supported path and compares with the SSE2 path bit for bit; returns the rays that hit.
size_t expect_same_on_all_paths(Bvh& bvh, const std::vector<Ray>& rays, const char* what) {
  bvh.set_simd_path(SimdPath::kSse2);
  std::vector<Answer> ref(rays.size());
  size_t hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    ref[i] = ask(bvh, rays[i]);
    hits += ref[i].hit;
  }
  for (SimdPath p : supported_simd_paths()) {
    if (p == SimdPath::kSse2) continue;
    bvh.set_simd_path(p);
    size_t differ = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      const Answer a = ask(bvh, rays[i]);
      if (a == ref[i]) continue;
      if (++differ <= 3)
        ADD_FAILURE() << what << ": " << kSimdPathNames[size_t(p)] << " differs from sse2 on ray " << i << " ("
                      << describe(rays[i]) << "): hit " << a.hit << "/" << ref[i].hit << " t " << std::hex << a.t
                      << "/" << ref[i].t << " b1 " << a.b1 << "/" << ref[i].b1 << " b2 " << a.b2 << "/" << ref[i].b2
                      << std::dec << " prim " << a.prim << "/" << ref[i].prim << " occluded " << a.occluded << "/"
                      << ref[i].occluded;
    }
    EXPECT_EQ(differ, 0u) << what << " on " << kSimdPathNames[size_t(p)] << " of " << rays.size() << " rays";
  }
  bvh.set_simd_path(best_simd_path());
  return hits;
}

void report_paths() {
  for (SimdPath p : {SimdPath::kSse2, SimdPath::kAvx2, SimdPath::kAvx512})
    if (!simd_path_supported(p)) std::printf("this CPU cannot run the %s path: not compared\n", kSimdPathNames[size_t(p)].data());
}

Vec3 unit(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const float z = 1.f - 2.f * u(rng), phi = 2.f * kPi * u(rng), r = std::sqrt(std::max(0.f, 1.f - z * z));
  return Vec3(r * std::cos(phi), r * std::sin(phi), z);
}

// Rays aimed at the mesh's features from random points of `from`: at vertices, at points on edges, along the
// triangles' planes (grazing, a hair to either side), axis-parallel through vertices, and in random directions.
std::vector<Ray> feature_rays(const TriangleMesh& m, const Bounds3& from, size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const auto pick = [&](size_t size) { return std::min(size_t(u(rng) * float(size)), size - 1); };
  std::vector<Ray> rays;
  rays.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec3 o = from.lo + Vec3(u(rng), u(rng), u(rng)) * (from.hi - from.lo);
    const glm::uvec3 f = m.faces[pick(m.faces.size())];
    const Vec3 a = m.p[f.x], b = m.p[f.y], c = m.p[f.z];
    Ray r;
    switch (i % 6) {
      case 0: r = Ray{o, a - o}; break;                                       // a vertex
      case 1: { const float s = u(rng); r = Ray{o, (1.f - s) * a + s * b - o}; break; }  // an edge
      case 2: {                                                               // grazing along the triangle's plane
        const Vec3 nrm = glm::normalize(glm::cross(b - a, c - a));
        const Vec3 in_plane = glm::normalize((b - a) * (u(rng) - 0.5f) + (c - a) * (u(rng) - 0.5f));
        const Vec3 start = (a + b + c) / 3.f - 4.f * in_plane;
        r = Ray{start + nrm * (1e-6f * (u(rng) - 0.5f)), in_plane + nrm * (1e-5f * (u(rng) - 0.5f))};
        break;
      }
      case 3: {                                                               // axis-parallel through a vertex
        const int axis = int(pick(3));
        Vec3 d(0.f);
        d[axis] = u(rng) < 0.5f ? -1.f : 1.f;
        r = Ray{a - 3.f * d, d};
        break;
      }
      case 4: r = Ray{a, unit(rng)}; break;                                   // from a vertex
      default: r = Ray{o, unit(rng)}; break;                                  // random
    }
    if (i % 7 == 3) r.tmax = 0.5f + 3.f * u(rng);
    rays.push_back(r);
  }
  return rays;
}

TEST(BvhSimdPaths, DefaultIsTheWidestSupportedPath) {
  report_paths();
  const auto paths = supported_simd_paths();
  ASSERT_FALSE(paths.empty());
  EXPECT_EQ(paths.front(), SimdPath::kSse2);
  EXPECT_EQ(paths.back(), best_simd_path());
  std::vector<Triangle> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  Bvh bvh = Bvh::build(tris, {});
  EXPECT_EQ(bvh.simd_path(), best_simd_path());
  for (SimdPath p : paths) {
    bvh.set_simd_path(p);
    EXPECT_EQ(bvh.simd_path(), p);
    EXPECT_TRUE(bvh.occluded(Ray{{0.2f, 0.2f, 1}, {0, 0, -1}}));
  }
}

TEST(BvhSimdPaths, MeshesGiveBitwiseTheSameHits) {
  report_paths();
  struct Case {
    const char* name;
    TriangleMesh mesh;
  };
  Case cases[] = {{"icosphere", make_icosphere({0.3f, -0.2f, 0.1f}, 1.f, 5)},
                  {"box grid", make_box_grid({-1.f, -0.5f, -2.f}, {1.3f, 0.7f, 0.9f}, 40)},
                  {"needle cylinder", make_needle_cylinder({0.1f, -1.f, 0.2f}, 0.5f, 2.f, 5000)},
                  {"bumpy sphere", make_bumpy_sphere({0.f, 0.f, 0.f}, 1.f, 60000)}};
  uint32_t seed = 1;
  for (Case& c : cases) {
    const std::vector<Triangle> tris = c.mesh.triangles();
    Bvh bvh = Bvh::build(tris, {});
    Bounds3 inner = c.mesh.bounds(), outer = inner;
    const Vec3 centre = inner.centroid(), ext = inner.diagonal();
    inner = Bounds3{centre - 0.2f * ext, centre + 0.2f * ext};
    outer = Bounds3{centre - 1.5f * ext, centre + 1.5f * ext};
    const size_t n = testing::scaled(25000);
    const size_t hits_in = expect_same_on_all_paths(bvh, feature_rays(c.mesh, inner, n, seed++), c.name);
    const size_t hits_out = expect_same_on_all_paths(bvh, feature_rays(c.mesh, outer, n, seed++), c.name);
    EXPECT_GT(hits_in, n / 2) << c.name;
    EXPECT_GT(hits_out, n / 4) << c.name;
  }
}

TEST(BvhSimdPaths, SoupsWithDegenerateAndCoincidentPrimitivesGiveBitwiseTheSameHits) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  const auto point = [&](float s) { return Vec3(u(rng), u(rng), u(rng)) * s; };
  std::vector<Triangle> tris;
  std::vector<Sphere> spheres;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 c = point(10.f);
    switch (i % 6) {
      case 0: tris.push_back({c, c, c}); break;                                          // a point
      case 1: tris.push_back({point(1e4f), point(1e4f), point(1e4f)}); break;            // huge
      case 2: tris.push_back({c, c + point(1e-4f), c + point(1e-4f)}); break;            // tiny
      case 3: tris.push_back({c, c + point(2.f), c + point(2.f)}); tris.push_back(tris.back()); break;  // twins
      default: tris.push_back({c, c + point(2.f), c + point(2.f)}); break;
    }
  }
  // Coplanar quads split along a diagonal, as scene walls are: rays through the diagonal tie between two triangles.
  for (int i = 0; i < 50; ++i) {
    const Vec3 c = point(8.f);
    tris.push_back({c, c + Vec3(1, 0, 0), c + Vec3(1, 1, 0)});
    tris.push_back({c, c + Vec3(1, 1, 0), c + Vec3(0, 1, 0)});
  }
  for (int i = 0; i < 100; ++i) spheres.push_back({point(10.f), 0.1f + 0.5f * (u(rng) + 1.f)});
  for (int i = 0; i < 8; ++i) spheres.push_back({Vec3(3.f, 3.f, 3.f), 0.2f + 0.1f * float(i)});  // nested
  Bvh bvh = Bvh::build(tris, spheres);
  std::vector<Ray> rays;
  for (size_t i = 0; i < testing::scaled(100000); ++i) {
    Ray r{point(20.f), point(1.f)};
    if (i % 4 == 1) r.d[i % 3] = 0.f;
    if (i % 4 == 2) r.tmax = 5.f + 10.f * (u(rng) + 1.f);
    if (i % 8 == 3) r.o = tris[(i * 7) % tris.size()].p0;
    if (i % 8 == 5) {  // through a quad's diagonal
      const Triangle& q = tris[tris.size() - 100 + 2 * ((i / 8) % 50)];
      const float s = 0.5f * (u(rng) + 1.f);
      const Vec3 target = q.p0 + s * (q.p2 - q.p0);
      r = Ray{target + point(3.f), Vec3(0.f)};
      r.d = target - r.o;
    }
    rays.push_back(r);
  }
  expect_same_on_all_paths(bvh, rays, "soup");
}

// Renders a window of a project scene on every path and compares the pixels' SHA-256.
TEST(BvhSimdPaths, RenderedTilesAreBitwiseTheSame) {
  for (const char* file : {"cbox_area_light.json", "cbox_glass.json", "sky_sun.json"}) {
    LoadedScene loaded = load_scene_file(std::filesystem::path(TESSERA_SOURCE_DIR) / "scenes" / file);
    Scene& scene = loaded.scene;
    RenderOptions o;
    o.spp = 4;
    o.seed = 11;
    o.variance = true;
    o.tile_size = 16;
    const int x0 = scene.width / 2 - 40, y0 = scene.height / 2 - 24;
    o.window = PixelWindow{x0, y0, x0 + 80, y0 + 48};
    std::string ref;
    for (SimdPath p : supported_simd_paths()) {
      scene.bvh.set_simd_path(p);
      const RenderResult r = render(scene, o);
      Sha256 h;
      h.update({reinterpret_cast<const uint8_t*>(r.image.rgb.data()), r.image.rgb.size() * sizeof(float)});
      for (const auto& [name, ch] : r.image.extra)
        h.update({reinterpret_cast<const uint8_t*>(ch.data()), ch.size() * sizeof(float)});
      const std::string hash = h.hex();
      if (p == SimdPath::kSse2) ref = hash;
      EXPECT_EQ(hash, ref) << file << " on " << kSimdPathNames[size_t(p)];
    }
  }
}

}  // namespace
}  // namespace tessera
