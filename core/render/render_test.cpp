// Image-level tests of the direct integrator against closed forms: a point light and a rectangular emitter above a
// diffuse plane, the white furnace, index-matched refraction, camera and environment orientation, emitter sides,
// the NaN/Inf guard, every course scene, and bitwise tile invariance. Tolerances are either float rounding or k
// standard errors of each pixel's mean, estimated from its own samples (RenderOptions::variance); the sample
// variance of stratified samples overestimates the variance of their mean, so these bounds are conservative.
#include "core/render/render.h"

#include "core/render/path_integrator.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_closed_forms.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>

namespace tessera {
namespace {

using json = nlohmann::json;
using testing::Vec3d;
namespace fs = std::filesystem;

// Number of standard errors a pixel may deviate. Each test checks a few hundred pixels; for a Gaussian error the
// chance that any of 1000 pixels passes 5 sigma is 6e-4, and the stratified samples' overestimated variance makes it
// smaller still. The renders are deterministic, so a passing test keeps passing.
constexpr double kSigmas = 5.0;

class RenderTest : public testing::TempDirTest {
 protected:
  Scene load(const json& s, const LoadOptions& opt = {}) {
    return load_scene_file(write_scene("scene.json", s), opt).scene;
  }
  // A scene with a camera, a film, white and grey diffuse materials, no point light and no objects yet.
  static json base(int w, int h, const Vec3& pos, const Vec3& at, const Vec3& up, double fov, int spp) {
    return json{{"integrator", {{"type", "intersection_test"}, {"spp", spp}, {"point_light_flux", {0, 0, 0}}}},
                {"film", {{"resolution", {w, h}}}},
                {"camera", {{"position", {pos.x, pos.y, pos.z}}, {"look_at", {at.x, at.y, at.z}},
                            {"ref_up", {up.x, up.y, up.z}}, {"fov", fov}}},
                {"textures", {{"white", {{"type", "constant"}, {"color", {1, 1, 1}}}},
                              {"grey", {{"type", "constant"}, {"color", {0.8, 0.5, 0.25}}}}}},
                {"materials", {{"white", {{"type", "diffuse"}, {"texture_name", "white"}}},
                               {"grey", {{"type", "diffuse"}, {"texture_name", "grey"}}}}},
                {"objects", json::array()}};
  }
  // A 100 x 100 diffuse floor at y = 0 facing +y.
  json floor(const std::string& material) {
    write("floor.obj", testing::rect_obj(Vec3(-50.f, 0.f, -50.f), Vec3(0.f, 0.f, 100.f), Vec3(100.f, 0.f, 0.f)));
    return {{"type", "mesh"}, {"path", "floor.obj"}, {"material_name", material}};
  }
};

const Vec3d kGrey(0.8, 0.5, 0.25);

// Where the camera ray (o, d) meets the plane y = 0 (d.y < 0 assumed).
Vec3d on_floor(const Vec3d& o, const Vec3d& d) { return o + (-o.y / d.y) * d; }

TEST_F(RenderTest, PointLightOverPlaneMatchesFootprintAverageToOnePermille) {
  // 256 stratified samples per pixel: measured worst error 7.7e-4 at 64 spp, see the printout for 256.
  const int w = 32, h = 24, spp = 256;
  json s = base(w, h, Vec3(0.f, 1.5f, 2.5f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 50.0, spp);
  const Vec3d light(0.3, 1.0, -0.2), flux(4.0, 8.0, 12.0);
  s["integrator"]["point_light_position"] = {light.x, light.y, light.z};
  s["integrator"]["point_light_flux"] = {flux.x, flux.y, flux.z};
  s["objects"].push_back(floor("grey"));
  const Scene scene = load(s);
  const RenderResult res = render(scene, RenderOptions{});
  const testing::CourseCamera cam(Vec3d(0, 1.5, 2.5), Vec3d(0), Vec3d(0, 1, 0), 50.0, w, h);
  double worst = 0.0;
  for (int row = 0; row < h; ++row)
    for (int px = 0; px < w; ++px) {
      // L = albedo/pi * flux/(4 pi d^2) * cos, cos = height/d: the footprint average by a 32 x 32 midpoint rule
      // in double (its own error is below 1e-5 relative for this smooth integrand).
      const double g = testing::pixel_average(cam, px, row, 32, [&](const Vec3d& o, const Vec3d& d) {
        const Vec3d x = on_floor(o, d);
        const double dist = glm::length(light - x);
        return light.y / (4.0 * std::numbers::pi * std::numbers::pi * dist * dist * dist);
      });
      const Vec3 got = res.image.at(px, row);
      for (int c = 0; c < 3; ++c) {
        const double ref = kGrey[c] * flux[c] * g;
        const double rel = std::abs(double(got[c]) - ref) / ref;
        worst = std::max(worst, rel);
        ASSERT_LE(rel, 1e-3) << "pixel " << px << "," << row << " channel " << c << ": " << got[c] << " vs " << ref;
      }
    }
  std::printf("point light: worst relative pixel error %.2e at %d spp\n", worst, spp);
}

// Renders the rectangle-over-plane scene and checks every pixel against Lambert's polygon formula; returns the mean
// over pixels of the variance of one pixel's mean (green channel).
double check_rect_light(const Scene& scene, int w, int h, const char* label) {
  RenderOptions ro;
  ro.variance = true;
  const RenderResult res = render(scene, ro);
  const std::vector<Vec3d> poly = {{-0.5, 1, -0.5}, {0.5, 1, -0.5}, {0.5, 1, 0.5}, {-0.5, 1, 0.5}};
  const Vec3d radiance(2.0, 3.0, 4.0);
  const testing::CourseCamera cam(Vec3d(0, 0.9, 0), Vec3d(0), Vec3d(0, 0, -1), 100.0, w, h);
  double sum_diff = 0, sum_var = 0, mean_var = 0;
  int worst_px = 0, worst_row = 0;
  double worst_z = 0;
  for (int row = 0; row < h; ++row)
    for (int px = 0; px < w; ++px) {
      const double e = testing::pixel_average(cam, px, row, 16, [&](const Vec3d& o, const Vec3d& d) {
        return testing::polygon_irradiance(on_floor(o, d), Vec3d(0, 1, 0), poly, 1.0);
      });
      const Vec3 got = res.image.at(px, row);
      const size_t i = size_t(row) * size_t(w) + size_t(px);
      for (int c = 0; c < 3; ++c) {
        const double ref = kGrey[c] / std::numbers::pi * radiance[c] * e;
        const double var = res.image.extra.at(c == 0 ? "variance.R" : c == 1 ? "variance.G" : "variance.B")[i];
        const double tol = kSigmas * std::sqrt(var) + 1e-5 * ref;
        EXPECT_NEAR(got[c], ref, tol) << label << " pixel " << px << "," << row << " channel " << c;
        const double z = std::abs(got[c] - ref) / std::sqrt(var);
        if (z > worst_z) worst_z = z, worst_px = px, worst_row = row;
        sum_diff += got[c] - ref;
        sum_var += var;
      }
      mean_var += res.image.extra.at("variance.G")[i];
    }
  // All pixels together: a bias of a fraction of a standard error per pixel shows up here.
  EXPECT_LE(std::abs(sum_diff), kSigmas * std::sqrt(sum_var)) << label;
  std::printf("%s: worst |z| %.2f at %d,%d; aggregate z %.2f; %.3fs\n", label, worst_z, worst_px, worst_row,
              sum_diff / std::sqrt(sum_var), res.seconds);
  return mean_var / (w * h);
}

TEST_F(RenderTest, RectangleLightOverPlaneMatchesPolygonIrradiance) {
  // A 1 x 1 emitter at height 1 facing down onto the floor; the camera sits between them looking straight down
  // (a pinhole occludes nothing) and sees past the emitter's edges.
  const int w = 24, h = 24;
  json s = base(w, h, Vec3(0.f, 0.9f, 0.f), Vec3(0.f), Vec3(0.f, 0.f, -1.f), 100.0, 64);
  s["objects"].push_back(floor("grey"));
  write("light.obj", testing::rect_obj(Vec3(-0.5f, 1.f, -0.5f), Vec3(1.f, 0.f, 0.f), Vec3(0.f, 0.f, 1.f)));
  s["objects"].push_back({{"type", "mesh"}, {"path", "light.obj"}, {"light", {{"type", "area"}, {"radiance", {2, 3, 4}}}}});
  s["integrator"]["area_sampling"] = "solid_angle";
  const Scene solid = load(s);
  ASSERT_EQ(solid.area_lights.at(0).rects.size(), 1u);
  const double v_solid = check_rect_light(solid, w, h, "spherical rectangle");
  s["integrator"]["area_sampling"] = "area";
  const double v_area = check_rect_light(load(s), w, h, "area sampling");
  std::printf("rectangle light: mean pixel variance, area / spherical rectangle = %.2f\n", v_area / v_solid);
  // The default: projected solid angle close up, warped area farther (the floor is 1 below a 1 x 1 light).
  s["integrator"]["area_sampling"] = "auto";
  const double v_auto = check_rect_light(load(s), w, h, "auto (warped)");
  std::printf("rectangle light: mean pixel variance, spherical rectangle / auto = %.2f\n", v_solid / v_auto);
  EXPECT_GT(v_solid / v_auto, 1.5);
  // Measured 16.0 (same spp, one light sample each); the pixel-footprint part of the variance is common to both.
  EXPECT_GT(v_area / v_solid, 4.0);
  // Four light samples per camera sample: still unbiased, and the light-sampling part of the variance drops.
  s["integrator"]["area_sampling"] = "solid_angle";
  s["integrator"]["light_samples"] = 4;
  const double v_four = check_rect_light(load(s), w, h, "4 light samples");
  std::printf("rectangle light: mean pixel variance, 1 / 4 light samples = %.2f\n", v_solid / v_four);
  EXPECT_GT(v_solid / v_four, 2.0);
}

TEST_F(RenderTest, WhiteFurnace) {
  // A white diffuse sphere under a uniform white environment reflects exactly what arrives: 1 everywhere.
  const int w = 16, h = 16;
  json s = base(w, h, Vec3(0.f, 0.f, 4.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 40.0, 16);
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}, {"material_name", "white"}});
  s["environment_map"] = {{"texture_name", "white"}};
  {
    // A constant environment is sampled by the cosine lobe: every sample is exactly 1.
    const RenderResult res = render(load(s), RenderOptions{});
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(res.image.at(x, y)[c], 1.f, 1e-6f) << x << "," << y;
  }
  // The same through an image map of ones, with each environment strategy: unbiased within the bound.
  Image ones = Image::make(16, 8);
  std::fill(ones.rgb.begin(), ones.rgb.end(), 1.f);
  write_image("white.exr", ones);
  s["textures"]["white_map"] = {{"type", "image"}, {"path", "white.exr"}};
  s["environment_map"] = {{"texture_name", "white_map"}};
  for (const char* mode : {"mis", "importance", "cosine", "uniform"}) {
    s["integrator"]["env_sampling"] = mode;
    RenderOptions ro;
    ro.variance = true;
    const RenderResult res = render(load(s), ro);
    double sum_diff = 0, sum_var = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double var = res.image.extra.at("variance.G")[size_t(y * w + x)];
        const double got = res.image.at(x, y).y;
        EXPECT_NEAR(got, 1.0, kSigmas * std::sqrt(var) + 1e-6) << mode << " " << x << "," << y;
        sum_diff += got - 1.0;
        sum_var += var;
      }
    EXPECT_LE(std::abs(sum_diff), kSigmas * std::sqrt(sum_var) + 1e-5) << mode;
    std::printf("furnace %-10s mean pixel sd %.4f, aggregate z %.2f\n", mode, std::sqrt(sum_var / (w * h)),
                sum_var > 0 ? sum_diff / std::sqrt(sum_var) : 0.0);
  }
}

// A textured wall at z = -2 lit by a point light between it and a sphere at the origin: the sphere's shadow falls
// away from the wall, so an index-matched sphere must vanish completely.
TEST_F(RenderTest, IndexMatchedRefractionSphereIsInvisible) {
  const int w = 32, h = 32;
  Image tex = Image::make(8, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) tex.set(x, y, Vec3(0.2f + 0.1f * float(x), 0.9f - 0.1f * float(y), float((x + y) % 2)));
  write_image("wall.exr", tex);
  write("wall.obj", testing::rect_obj(Vec3(-5.f, -5.f, -2.f), Vec3(10.f, 0.f, 0.f), Vec3(0.f, 10.f, 0.f), true));
  json s = base(w, h, Vec3(0.f, 0.f, 4.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 40.0, 4);
  s["integrator"]["point_light_position"] = {0, 0, -1};
  s["integrator"]["point_light_flux"] = {10, 10, 10};
  s["textures"]["wall"] = {{"type", "image"}, {"path", "wall.exr"}};
  s["materials"]["wall"] = {{"type", "diffuse"}, {"texture_name", "wall"}};
  s["objects"].push_back({{"type", "mesh"}, {"path", "wall.obj"}, {"material_name", "wall"}});
  const RenderResult without = render(load(s), RenderOptions{});
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 0.5}, {"material_name", "glass"}});
  auto with_eta = [&](double eta) {
    s["materials"]["glass"] = {{"type", "refraction"}, {"eta", eta}};
    return render(load(s), RenderOptions{});
  };
  const RenderResult matched = with_eta(1.0);
  double worst = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const float a = without.image.at(x, y)[c], b = matched.image.at(x, y)[c];
        // Rays through the sphere restart from its surface (offset by the rounding bound): the wall point moves by
        // a few ulps of the coordinates, so the radiance agrees to float rounding, not bitwise.
        EXPECT_NEAR(b, a, 1e-5f * std::abs(a) + 1e-7f) << x << "," << y << " channel " << c;
        worst = std::max(worst, double(std::abs(a - b)) / std::max(1e-7, double(std::abs(a))));
      }
  std::printf("eta = 1 sphere: worst relative difference %.2e\n", worst);
  // The test can fail: a glass sphere (eta 1.5) visibly changes the image.
  const RenderResult glass = with_eta(1.5);
  double max_diff = 0;
  for (size_t i = 0; i < glass.image.rgb.size(); ++i)
    max_diff = std::max(max_diff, double(std::abs(glass.image.rgb[i] - without.image.rgb[i])));
  EXPECT_GT(max_diff, 0.05);
}

TEST_F(RenderTest, SpecularChainsStopAtMaxDepth) {
  // Looking through an index-matched sphere at an emitting wall takes two refractions.
  const int w = 5, h = 5;
  write("wall.obj", testing::rect_obj(Vec3(-5.f, -5.f, -2.f), Vec3(10.f, 0.f, 0.f), Vec3(0.f, 10.f, 0.f)));
  json s = base(w, h, Vec3(0.f, 0.f, 4.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 10.0, 1);
  s["materials"]["glass"] = {{"type", "refraction"}, {"eta", 1.0}};
  s["objects"].push_back({{"type", "mesh"}, {"path", "wall.obj"}, {"light", {{"type", "area"}, {"radiance", {1, 2, 3}}}}});
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}, {"material_name", "glass"}});
  s["integrator"]["max_depth"] = 1;
  EXPECT_EQ(render(load(s), RenderOptions{}).image.at(2, 2), Vec3(0.f));
  s["integrator"]["max_depth"] = 2;
  EXPECT_EQ(render(load(s), RenderOptions{}).image.at(2, 2), Vec3(1.f, 2.f, 3.f));
}

TEST_F(RenderTest, EmittersShowRadianceOnTheirEmittingSideOnly) {
  const int w = 4, h = 4;
  json s = base(w, h, Vec3(0.f, 0.f, 4.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 20.0, 2);
  // Facing the camera (+z), then turned away.
  write("front.obj", testing::rect_obj(Vec3(-5.f, -5.f, -2.f), Vec3(10.f, 0.f, 0.f), Vec3(0.f, 10.f, 0.f)));
  write("back.obj", testing::rect_obj(Vec3(-5.f, -5.f, -2.f), Vec3(0.f, 10.f, 0.f), Vec3(10.f, 0.f, 0.f)));
  for (const char* file : {"front.obj", "back.obj"}) {
    s["objects"] = json::array({{{"type", "mesh"}, {"path", file}, {"light", {{"type", "area"}, {"radiance", {1, 2, 3}}}}}});
    const RenderResult res = render(load(s), RenderOptions{});
    const Vec3 expect = std::string(file) == "front.obj" ? Vec3(1.f, 2.f, 3.f) : Vec3(0.f);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) EXPECT_EQ(res.image.at(x, y), expect) << file << " " << x << "," << y;
  }
  // A spherical emitter seen from outside.
  s["objects"] = json::array({{{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 3}, {"light", {{"type", "area"}, {"radiance", {1, 2, 3}}}}}});
  EXPECT_EQ(render(load(s), RenderOptions{}).image.at(1, 1), Vec3(1.f, 2.f, 3.f));
}

TEST_F(RenderTest, CameraAndEnvironmentOrientation) {
  // Map: left half (u < 1/2) red, upper half (v < 1/2) green. Looking down -z, the right of the picture looks at
  // phi just above 0 (u small: red) and the left at phi just below 2 pi (u near 1: not red); the top row looks up
  // (v < 1/2: green). Blending reaches half a texel (11.25 degrees) from the seams, away from the corners checked.
  Image map = Image::make(16, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) map.set(x, y, Vec3(x < 8 ? 1.1f : 0.1f, y < 4 ? 1.1f : 0.1f, 0.1f));
  write_image("env.exr", map);
  const int w = 8, h = 8;
  json s = base(w, h, Vec3(0.f), Vec3(0.f, 0.f, -1.f), Vec3(0.f, 1.f, 0.f), 90.0, 4);
  s["textures"]["env"] = {{"type", "image"}, {"path", "env.exr"}};
  s["environment_map"] = {{"texture_name", "env"}};
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 50}}, {"radius", 0.1}, {"material_name", "white"}});
  const RenderResult res = render(load(s), RenderOptions{});
  auto near = [](const Vec3& a, const Vec3& b) { return glm::length(a - b) < 1e-5f; };
  EXPECT_PRED2(near, res.image.at(0, 0), Vec3(0.1f, 1.1f, 0.1f));          // top left: up, not red
  EXPECT_PRED2(near, res.image.at(w - 1, 0), Vec3(1.1f, 1.1f, 0.1f));      // top right: up, red
  EXPECT_PRED2(near, res.image.at(0, h - 1), Vec3(0.1f, 0.1f, 0.1f));      // bottom left
  EXPECT_PRED2(near, res.image.at(w - 1, h - 1), Vec3(1.1f, 0.1f, 0.1f));  // bottom right
  // Without an environment, escaping rays are black.
  s.erase("environment_map");
  const RenderResult black = render(load(s), RenderOptions{});
  for (float v : black.image.rgb) EXPECT_EQ(v, 0.f);
}

TEST_F(RenderTest, NonFiniteSamplesAreDroppedAndCounted) {
  // scale * colour overflows to +Inf; a black diffuse sphere turns it into 0 * Inf = NaN.
  const int w = 6, h = 5, spp = 4;
  json s = base(w, h, Vec3(0.f, 0.f, 4.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 40.0, spp);
  s["textures"]["huge"] = {{"type", "constant"}, {"color", {3e38, 3e38, 3e38}}};
  s["textures"]["black"] = {{"type", "constant"}, {"color", {0, 0, 0}}};
  s["materials"]["black"] = {{"type", "diffuse"}, {"texture_name", "black"}};
  s["environment_map"] = {{"texture_name", "huge"}, {"scale", 3e38}};
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}, {"material_name", "black"}});
  RenderOptions ro;
  ro.variance = true;
  const RenderResult res = render(load(s), ro);
  EXPECT_EQ(res.counters.nonfinite, uint64_t(w * h * spp));
  for (float v : res.image.rgb) EXPECT_TRUE(std::isfinite(v));
  for (const auto& [name, ch] : res.image.extra)
    for (float v : ch) EXPECT_TRUE(std::isfinite(v)) << name;
}

TEST_F(RenderTest, VarianceOfMeanIsFiniteForHugeFiniteSamples) {
  // Samples near the float limit: their mean is finite, the variance of the mean must not overflow to Inf.
  const int w = 2, h = 2;
  json s = base(w, h, Vec3(0.f, 0.f, 4.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 40.0, 4);
  s["textures"]["huge"] = {{"type", "constant"}, {"color", {1e37, 1, 1}}};
  s["environment_map"] = {{"texture_name", "huge"}};
  s["objects"].push_back({{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 1}, {"material_name", "white"}});
  s["integrator"]["env_sampling"] = "uniform";
  RenderOptions ro;
  ro.variance = true;
  const RenderResult res = render(load(s), ro);
  for (const auto& [name, ch] : res.image.extra)
    for (float v : ch) EXPECT_TRUE(std::isfinite(v)) << name;
}

TEST_F(RenderTest, EveryCourseSceneRendersFiniteAndNonBlack) {
  for (const char* name : {"cbox.json", "cbox_no_light.json", "cbox_no_light_refract.json", "cbox_refract_textured.json"}) {
    LoadOptions opt;
    opt.force_direct = true;  // cbox.json asks for bdpt
    Scene scene = load_scene_file(fs::path(TESSERA_COURSE_DIR) / name, opt).scene;
    scene.width = 32;  // the camera does not depend on the resolution
    scene.height = 32;
    RenderOptions ro;
    ro.spp = 4;
    const RenderResult res = render(scene, ro);
    double sum = 0;
    for (float v : res.image.rgb) {
      ASSERT_TRUE(std::isfinite(v)) << name;
      sum += v;
    }
    EXPECT_EQ(res.counters.nonfinite, 0u) << name;
    EXPECT_GT(sum / double(res.image.rgb.size()), 1e-3) << name;
    std::printf("%s: mean %.4f, %.3fs\n", name, sum / double(res.image.rgb.size()), res.seconds);
  }
}

// render_pixel traces a pixel's samples two at a time (both camera rays before either sample is shaded, the path
// tracer's two paths side by side) with the pixel's seed table: the estimate must be bitwise that of tracing each
// sample alone, in order, through trace_sample with a sampler hashing per draw, for even and odd sample counts,
// replicates (including more than kMaxReplicates) and both integrators.
TEST_F(RenderTest, SamplesTracedInPairsGiveBitwiseTheEstimateOfOneAtATime) {
  for (const char* name : {"cbox_refract_textured.json", "glass_sphere.json"}) {  // direct lighting; path tracing
    Scene scene = load_scene_file(fs::path(TESSERA_COURSE_DIR) / name).scene;
    scene.width = 16;
    scene.height = 12;
    for (const uint32_t replicates : {1u, 2u, 3u, kMaxReplicates + 1})
      for (const uint32_t spp : {1u, 2u, 5u, 8u})
        for (int y = 0; y < scene.height; y += 5)
          for (int x = 0; x < scene.width; x += 3) {
            RayCounters paired_counters, single_counters;
            const PixelEstimate paired = render_pixel(scene, x, y, 99, spp, paired_counters, replicates);
            PixelAccumulator acc(std::min(replicates, kMaxReplicates));
            for (uint32_t s = 0; s < spp; ++s) {
              PixelSampler sampler = pixel_sampler(99, x, y, s, replicates);
              const Ray r = scene.camera.generate_pixel(x, y, sampler.next_2d(), scene.width, scene.height);
              acc.add(trace_sample(scene, r, sampler, single_counters));
            }
            const PixelEstimate single = acc.estimate();
            ASSERT_EQ(std::memcmp(&paired.mean, &single.mean, sizeof paired.mean), 0)
                << name << " pixel " << x << "," << y << " at " << spp << " spp, " << replicates << " replicates";
            ASSERT_EQ(std::memcmp(&paired.var_mean, &single.var_mean, sizeof paired.var_mean), 0) << name;
            ASSERT_EQ(paired_counters.rays, single_counters.rays) << name;
            ASSERT_EQ(paired_counters.camera, single_counters.camera) << name;
          }
  }
}

TEST_F(RenderTest, CropsAndTileSizesGiveBitwiseIdenticalPixels) {
  LoadOptions opt;
  opt.spp = 4;
  Scene scene = load_scene_file(fs::path(TESSERA_COURSE_DIR) / "cbox_refract_textured.json", opt).scene;
  scene.width = 37;
  scene.height = 29;
  RenderOptions whole_opt;
  whole_opt.variance = true;
  whole_opt.seed = 12345;
  const RenderResult whole = render(scene, whole_opt);
  // Odd-sized crops covering the picture, each with a different tile size; one on a single thread.
  const int xs[] = {0, 7, 20, 37}, ys[] = {0, 5, 18, 29};
  int tile = 1;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      RenderOptions ro = whole_opt;
      ro.window = PixelWindow{xs[i], ys[j], xs[i + 1], ys[j + 1]};
      ro.tile_size = tile;
      tile += 2;
      std::unique_ptr<tbb::global_control> one;
      if (i == 1 && j == 1) one = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 1);
      const RenderResult part = render(scene, ro);
      ASSERT_EQ(part.window, ro.window);
      for (int y = ro.window.y0; y < ro.window.y1; ++y)
        for (int x = ro.window.x0; x < ro.window.x1; ++x) {
          const Vec3 a = whole.image.at(x, y), b = part.image.at(x - ro.window.x0, y - ro.window.y0);
          ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "pixel " << x << "," << y << " in crop " << i << "," << j;
          for (const auto& [name, ch] : whole.image.extra) {
            const float va = ch[size_t(y * whole.image.width + x)];
            const float vb = part.image.extra.at(name)[size_t((y - ro.window.y0) * part.image.width + (x - ro.window.x0))];
            ASSERT_EQ(std::memcmp(&va, &vb, sizeof va), 0) << name << " at " << x << "," << y;
          }
        }
    }
  // A different seed changes the pixels (so the comparison above is not vacuous).
  RenderOptions other = whole_opt;
  other.seed = 54321;
  EXPECT_NE(render(scene, other).image.rgb, whole.image.rgb);
}

TEST_F(RenderTest, RowsFinalTellsEveryRowOnceInOrderWithItsFinalValues) {
  LoadOptions opt;
  opt.spp = 2;
  Scene scene = load_scene_file(fs::path(TESSERA_COURSE_DIR) / "cbox_refract_textured.json", opt).scene;
  scene.width = 23;
  scene.height = 31;
  RenderOptions ro;
  ro.variance = true;
  ro.keep_state = true;
  ro.tile_size = 4;
  ro.window = PixelWindow{2, 1, 23, 30};
  const RenderResult plain = render(scene, ro);
  for (const int threads : {1, 2, 5}) {
    std::atomic<int> in_call{0};
    int next = 0;
    bool overlapped = false;
    std::vector<std::pair<int, Image>> bands;  // (first row, the rows as told)
    std::vector<uint32_t> told_samples;
    RenderOptions o = ro;
    o.rows_final = [&](const Image& film, const RenderState& state, int y0, int y1) {
      if (in_call.fetch_add(1) != 0) overlapped = true;
      EXPECT_EQ(y0, next) << threads;
      EXPECT_GT(y1, y0) << threads;
      next = y1;
      bands.emplace_back(y0, image_rows(film, y0, y1));
      told_samples.insert(told_samples.end(), state.samples.begin() + y0 * film.width,
                          state.samples.begin() + y1 * film.width);
      in_call.fetch_sub(1);
    };
    tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(threads));
    tbb::task_arena arena(threads);
    RenderResult res;
    arena.execute([&] { res = render(scene, o); });
    EXPECT_FALSE(overlapped) << threads;
    EXPECT_EQ(next, 29) << threads;  // every row of the window, once
    // The rows were final when told, and telling them changed no pixel.
    EXPECT_EQ(res.image.rgb, plain.image.rgb) << threads;
    for (const auto& [y0, band] : bands) {
      const Image now = image_rows(res.image, y0, y0 + band.height);
      EXPECT_EQ(band.rgb, now.rgb) << threads << ", rows from " << y0;
      EXPECT_EQ(band.extra, now.extra) << threads << ", rows from " << y0;
    }
    EXPECT_EQ(told_samples, res.state.samples) << threads;
  }
}

}  // namespace
}  // namespace tessera
