// Path tracer tests, each against a closed form or a statistic: furnaces (a closed diffuse enclosure of albedo rho
// with uniform inner emission Le shows Le / (1 - rho) in every pixel, for a tessellated sphere and a box, every
// profile), white furnaces for glass and a fully reflecting rough conductor, the three profiles agreeing on one
// scene within their error estimates, one-sided emitters, and bitwise tile/crop invariance.
#include "core/render/path_integrator.h"

#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstring>
#include <sstream>

namespace tessera {
namespace {

using json = nlohmann::json;

// A lat-long tessellated unit sphere around the origin, every triangle wound so that its normal points inward.
std::string inward_sphere_obj(int rings, int segments) {
  std::ostringstream os;
  std::vector<Vec3> v;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const float th = kPi * float(i) / float(rings), ph = 2.f * kPi * float(j) / float(segments);
      v.emplace_back(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
    }
  for (const Vec3& p : v) os << "v " << p.x << " " << p.y << " " << p.z << "\n";
  auto idx = [&](int i, int j) { return i * segments + (j % segments) + 1; };
  auto tri = [&](int a, int b, int c) {
    const Vec3 n = glm::cross(v[size_t(b - 1)] - v[size_t(a - 1)], v[size_t(c - 1)] - v[size_t(a - 1)]);
    if (glm::dot(n, v[size_t(a - 1)] + v[size_t(b - 1)] + v[size_t(c - 1)]) > 0.f) std::swap(b, c);  // face inward
    os << "f " << a << " " << b << " " << c << "\n";
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      if (i > 0) tri(idx(i, j), idx(i, j + 1), idx(i + 1, j));
      if (i + 1 < rings) tri(idx(i, j + 1), idx(i + 1, j + 1), idx(i + 1, j));
    }
  return os.str();
}

// The cube [-1, 1]^3 with faces as quads wound to face inward (each splits into a rectangle light part).
std::string inward_cube_obj() {
  return "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
         "f 1 2 3 4\nf 8 7 6 5\nf 1 5 6 2\nf 4 3 7 8\nf 1 4 8 5\nf 2 6 7 3\n";
}

// Samples per pixel for a test: n in the main build, fewer under sanitizers, never below 32 (two per replicate).
int test_spp(size_t n) { return int(std::max<size_t>(32, testing::scaled(n))); }

// The furnaces check every pixel against its own error estimate, which needs 16 samples per replicate: at 2 per
// replicate the rare long, bright paths of rho = 0.5-0.9 are missing from most replicates and the estimate comes out
// several times too small. So they run at full count in every build (a few seconds under sanitizers).
constexpr int kFurnaceSpp = 256;

json path_scene(int res, int spp) {
  return json{{"integrator", {{"type", "path"}, {"spp", spp}, {"max_depth", 1000}, {"point_light_flux", {0, 0, 0}}}},
              {"film", {{"resolution", {res, res}}}},
              {"camera", {{"position", {0, 0, 0}}, {"look_at", {0.3, 0.2, 1}}, {"ref_up", {0, 1, 0}}, {"fov", 90}}},
              {"textures", json::object()},
              {"materials", json::object()},
              {"objects", json::array()}};
}

class PathTracer : public testing::TempDirTest {
 protected:
  RenderResult render_scene(const json& s, uint64_t seed = 1, int tile = 16, PixelWindow window = {}) {
    const LoadedScene l = load_scene_file(write_scene("scene.json", s));
    EXPECT_EQ(l.scene.settings.integrator, IntegratorKind::kPath);
    RenderOptions opt;
    opt.seed = seed;
    opt.variance = true;
    opt.replicates = 16;  // unbiased variance estimates with enough degrees of freedom for 5-sigma bounds
    opt.tile_size = tile;
    opt.window = window;
    return render(l.scene, opt);
  }

  // Every pixel within 5 of its standard errors (+0.5%) of `expect`, and the image mean within 5 standard errors.
  void expect_uniform(const RenderResult& r, const Vec3& expect, const std::string& what) {
    const Image& im = r.image;
    double sum = 0.0, var = 0.0;
    const size_t n = size_t(im.width) * size_t(im.height);
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x) {
        const size_t i = size_t(y) * size_t(im.width) + size_t(x);
        for (int c = 0; c < 3; ++c) {
          const double v = im.at(x, y)[c];
          const double se = std::sqrt(double(im.extra.at(c == 0 ? "variance.R" : c == 1 ? "variance.G" : "variance.B")[i]));
          EXPECT_NEAR(v, expect[c], 5.0 * se + 0.005 * expect[c]) << what << " pixel " << x << "," << y << " channel " << c;
          if (c == 1) {
            sum += v;
            var += se * se;
          }
        }
      }
    EXPECT_NEAR(sum / double(n), expect.y, 5.0 * std::sqrt(var) / double(n) + 1e-4 * expect.y) << what << " image mean";
    EXPECT_EQ(r.counters.nonfinite, 0u) << what;
  }
};

TEST_F(PathTracer, FurnaceSphereShowsLeOverOneMinusRho) {
  write("sphere.obj", inward_sphere_obj(16, 32));
  for (float rho : {0.5f, 0.9f}) {
    for (const char* profile : {"MIS", "NEE"}) {
      json s = path_scene(6, kFurnaceSpp);
      s["integrator"]["profile"] = profile;
      s["textures"]["albedo"] = {{"type", "constant"}, {"color", {rho, rho, rho}}};
      s["materials"]["wall"] = {{"type", "diffuse"}, {"texture_name", "albedo"}};
      s["objects"].push_back({{"type", "mesh"}, {"path", "sphere.obj"}, {"material_name", "wall"},
                              {"light", {{"type", "area"}, {"radiance", {1, 1, 1}}}}});
      expect_uniform(render_scene(s), Vec3(1.f / (1.f - rho)), std::string(profile) + " rho " + std::to_string(rho));
    }
  }
}

TEST_F(PathTracer, FurnaceBoxEveryProfileAndRoulette) {
  write("box.obj", inward_cube_obj());
  for (const char* profile : {"MIS", "NEE", "RW"}) {
    for (float rr : {0.1f, 0.f}) {
      json s = path_scene(6, kFurnaceSpp);
      s["integrator"]["profile"] = profile;
      s["integrator"]["rr_threshold"] = rr;
      if (rr == 0.f) s["integrator"]["max_depth"] = 80;  // without roulette: truncation bias 0.8^80 ~ 2e-8
      s["textures"]["albedo"] = {{"type", "constant"}, {"color", {0.5, 0.7, 0.8}}};
      s["materials"]["wall"] = {{"type", "diffuse"}, {"texture_name", "albedo"}};
      s["objects"].push_back({{"type", "mesh"}, {"path", "box.obj"}, {"material_name", "wall"},
                              {"light", {{"type", "area"}, {"radiance", {0.5, 0.5, 0.5}}}}});
      const RenderResult r = render_scene(s);
      expect_uniform(r, 0.5f / (Vec3(1.f) - Vec3(0.5f, 0.7f, 0.8f)), std::string(profile) + " rr " + std::to_string(rr));
    }
  }
}

TEST_F(PathTracer, GlassSphereInAWhiteEnvironmentStaysWhite) {
  json s = path_scene(12, test_spp(64));
  s["integrator"]["max_depth"] = 64;
  s["camera"] = {{"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}, {"ref_up", {0, 1, 0}}, {"fov", 35}};
  s["textures"]["white"] = {{"type", "constant"}, {"color", {1, 1, 1}}};
  s["materials"]["glass"] = {{"type", "glass"}, {"eta", 1.5}};
  s["environment_map"] = {{"texture_name", "white"}};
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}, {"material_name", "glass"}});
  const RenderResult r = render_scene(s);
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.image.at(x, y)[c], 1.f, 1e-3f) << x << "," << y;
}

TEST_F(PathTracer, FullyReflectingRoughMetalInAWhiteEnvironmentLosesOnlyShadowing) {
  // F = 1 (etaT = k = 0) on a convex sphere: every pixel shows the single-scattering albedo, at most 1 and at least
  // 1 - 0.15 alpha at normal incidence (see bsdf_test); over the silhouette grazing angles lose more.
  json s = path_scene(12, 128);  // per-pixel error bounds: full count in every build, as the furnaces
  s["camera"] = {{"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}, {"ref_up", {0, 1, 0}}, {"fov", 35}};
  s["textures"]["white"] = {{"type", "constant"}, {"color", {1, 1, 1}}};
  s["materials"]["metal"] = {{"type", "roughconductor"}, {"alpha_x", 0.3}, {"alpha_y", 0.3}, {"etaT", {0, 0, 0}}, {"k", {0, 0, 0}}};
  s["environment_map"] = {{"texture_name", "white"}};
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}, {"material_name", "metal"}});
  const RenderResult r = render_scene(s);
  const float centre = 0.25f * (r.image.at(5, 5).y + r.image.at(6, 5).y + r.image.at(5, 6).y + r.image.at(6, 6).y);
  EXPECT_GT(centre, 1.f - 0.15f * 0.3f);
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      const size_t i = size_t(y) * size_t(r.image.width) + size_t(x);
      EXPECT_LE(r.image.at(x, y).y, 1.f + 5.f * std::sqrt(r.image.extra.at("variance.G")[i]) + 1e-4f) << x << "," << y;
      EXPECT_GT(r.image.at(x, y).y, 0.5f) << x << "," << y;
    }
}

// A small scene with every kind of light and material: a diffuse checkerboard floor, a rough metal sphere, a glass
// sphere, a small emitting sphere, a rectangular light, the point light and a dim environment.
json mixed_scene(const std::string& profile, int spp) {
  json s = path_scene(10, spp);
  s["integrator"] = {{"type", "path"}, {"spp", spp}, {"max_depth", 8}, {"profile", profile},
                     {"point_light_position", {1.5, 2.5, 0}}, {"point_light_flux", {20, 20, 20}}};
  s["camera"] = {{"position", {0, 1.2, -4}}, {"look_at", {0, 0.4, 0}}, {"ref_up", {0, 1, 0}}, {"fov", 50}};
  s["textures"]["checks"] = {{"type", "checkerboard"}, {"color0", {0.7, 0.7, 0.7}}, {"color1", {0.2, 0.3, 0.6}},
                             {"tex_coordinate_generator", {{"type", "uvmapping2d"}, {"scale", {4, 4}}}}};
  s["textures"]["sky"] = {{"type", "constant"}, {"color", {0.2, 0.25, 0.3}}};
  s["materials"]["floor"] = {{"type", "diffuse"}, {"texture_name", "checks"}};
  s["materials"]["metal"] = {{"type", "roughconductor"}, {"alpha_x", 0.08}, {"alpha_y", 0.2},
                             {"etaT", {0.2, 0.9, 1.1}}, {"k", {3.9, 2.4, 2.2}}};
  s["materials"]["glass"] = {{"type", "glass"}, {"eta", 1.5}, {"T", {0.9, 1, 0.9}}};
  s["environment_map"] = {{"texture_name", "sky"}};
  s["objects"] = json::array();
  s["objects"].push_back({{"type", "mesh"}, {"path", "floor.obj"}, {"material_name", "floor"}});
  s["objects"].push_back({{"type", "mesh"}, {"path", "light.obj"}, {"light", {{"type", "area"}, {"radiance", {6, 6, 5}}}}});
  s["objects"].push_back({{"type", "sphere"}, {"center", {-0.6, 0.5, 0}}, {"radius", 0.5}, {"material_name", "metal"}});
  s["objects"].push_back({{"type", "sphere"}, {"center", {0.7, 0.45, -0.3}}, {"radius", 0.45}, {"material_name", "glass"}});
  s["objects"].push_back({{"type", "sphere"}, {"center", {0.2, 1.6, 0.8}}, {"radius", 0.08},
                          {"light", {{"type", "area"}, {"radiance", {80, 60, 40}}}}});
  return s;
}

class PathTracerMixed : public PathTracer {
 protected:
  void SetUp() override {
    PathTracer::SetUp();
    write("floor.obj", "v -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 4/4 3/3 2/2\n");
    write("light.obj", "v -0.5 2.5 -0.3\nv 0.5 2.5 -0.3\nv 0.5 2.5 0.5\nv -0.5 2.5 0.5\nf 1 2 3 4\n");
  }
};

TEST_F(PathTracerMixed, ProfilesConvergeToTheSameImage) {
  const int spp = int(std::max<size_t>(512, testing::scaled(1024)));  // the variance ordering needs enough samples
  std::vector<RenderResult> r;
  for (const char* p : {"MIS", "NEE", "RW"}) r.push_back(render_scene(mixed_scene(p, spp)));
  // The image means agree within 4.5 combined standard errors (each from its pixels' variance channels).
  auto mean_and_var = [](const RenderResult& res) {
    double sum = 0.0, var = 0.0;
    const auto& vg = res.image.extra.at("variance.G");
    for (int y = 0; y < res.image.height; ++y)
      for (int x = 0; x < res.image.width; ++x) {
        sum += res.image.at(x, y).y;
        var += vg[size_t(y) * size_t(res.image.width) + size_t(x)];
      }
    const double n = double(res.image.width) * res.image.height;
    return std::make_pair(sum / n, var / (n * n));
  };
  const auto mis = mean_and_var(r[0]);
  EXPECT_GT(mis.first, 0.05);
  for (size_t k = 1; k < r.size(); ++k) {
    const auto o = mean_and_var(r[k]);
    EXPECT_NEAR(o.first, mis.first, 4.5 * std::sqrt(mis.second + o.second)) << "profile " << k;
    EXPECT_EQ(r[k].counters.nonfinite, 0u);
  }
  // MIS has the smallest variance of the three at equal sample count on this scene.
  EXPECT_LT(mis.second, mean_and_var(r[1]).second);
  EXPECT_LT(mis.second, mean_and_var(r[2]).second);
}

TEST_F(PathTracerMixed, TilesAndCropsAreBitwiseInvariant) {
  const json s = mixed_scene("MIS", 16);
  const RenderResult whole = render_scene(s, 7, 16);
  const RenderResult small = render_scene(s, 7, 3);
  ASSERT_EQ(whole.image.rgb.size(), small.image.rgb.size());
  EXPECT_EQ(std::memcmp(whole.image.rgb.data(), small.image.rgb.data(), whole.image.rgb.size() * sizeof(float)), 0);
  const RenderResult crop = render_scene(s, 7, 2, PixelWindow{3, 2, 8, 9});
  for (int y = 2; y < 9; ++y)
    for (int x = 3; x < 8; ++x) {
      const Vec3 a = whole.image.at(x, y), b = crop.image.at(x - 3, y - 2);
      EXPECT_EQ(std::memcmp(&a, &b, sizeof(Vec3)), 0) << x << "," << y;
    }
  EXPECT_NE(std::memcmp(whole.image.rgb.data(), render_scene(s, 8, 16).image.rgb.data(),
                        whole.image.rgb.size() * sizeof(float)), 0) << "the seed must matter";
}

TEST_F(PathTracer, OneSidedEmitterDoesNotLeakLight) {
  // A light facing away from the only diffuse surface: nothing reaches it, under every profile.
  write("floor.obj", "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3 2\n");
  write("light.obj", "v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\nf 1 4 3 2\n");  // normal +y: away
  for (const char* p : {"MIS", "NEE", "RW"}) {
    json s = path_scene(6, 32);
    s["integrator"]["profile"] = p;
    // From below the light's plane the camera sees its back and the floor it faces away from.
    s["camera"] = {{"position", {0, 0.5, -3.5}}, {"look_at", {0, 0, 0}}, {"ref_up", {0, 1, 0}}, {"fov", 60}};
    s["textures"]["white"] = {{"type", "constant"}, {"color", {1, 1, 1}}};
    s["materials"]["floor"] = {{"type", "diffuse"}, {"texture_name", "white"}};
    s["objects"].push_back({{"type", "mesh"}, {"path", "floor.obj"}, {"material_name", "floor"}});
    s["objects"].push_back({{"type", "mesh"}, {"path", "light.obj"}, {"light", {{"type", "area"}, {"radiance", {10, 10, 10}}}}});
    const RenderResult r = render_scene(s);
    for (float v : r.image.rgb) EXPECT_EQ(v, 0.f) << p;
  }
}

}  // namespace
}  // namespace tessera
