// Adaptive sampling (--target-error) and the per-pixel error estimates: tile invariance, where the samples go,
// and how the achieved and predicted errors compare with an independent reference render.
#include "core/sampling/adaptive.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_error.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

namespace tessera {
namespace {

// A spheres-only scene (no assets): a ground sphere, a spherical light above a spherical occluder (soft shadow
// with a wide penumbra), a black background. Background pixels have zero variance; penumbra pixels the most.
Scene penumbra_scene(int w, int h) {
  const nlohmann::json j = nlohmann::json::parse(R"({
    "integrator": {"type": "intersection_test", "spp": 16, "point_light_flux": [0, 0, 0]},
    "film": {"resolution": [)" + std::to_string(w) + "," + std::to_string(h) + R"(]},
    "camera": {"position": [0, 2.2, 5], "look_at": [0, 0.4, 0], "fov": 40},
    "textures": {"white": {"type": "constant", "color": [0.8, 0.8, 0.8]}},
    "materials": {"white": {"type": "diffuse", "texture_name": "white"}},
    "objects": [
      {"type": "sphere", "center": [0, -1000, 0], "radius": 1000, "material_name": "white"},
      {"type": "sphere", "center": [0, 0.8, 0], "radius": 0.45, "material_name": "white"},
      {"type": "sphere", "center": [0.3, 2.6, -0.3], "radius": 0.6, "light": {"type": "area", "radiance": [6, 6, 6]}}
    ]
  })");
  auto no_assets = [](const std::string& p, const std::string&) -> std::filesystem::path {
    throw SceneError("unexpected asset " + p);
  };
  return load_scene_json(j, "penumbra", no_assets).scene;
}

void expect_same_bits(const Image& whole, const PixelWindow& ww, const Image& crop, const PixelWindow& cw) {
  ASSERT_TRUE(ww.contains(cw));
  for (int y = cw.y0; y < cw.y1; ++y)
    for (int x = cw.x0; x < cw.x1; ++x) {
      const Vec3 a = whole.at(x - ww.x0, y - ww.y0), b = crop.at(x - cw.x0, y - cw.y0);
      ASSERT_EQ(0, std::memcmp(&a, &b, sizeof a)) << "pixel " << x << "," << y;
      for (const auto& [name, ch] : whole.extra) {
        const float va = ch[size_t(y - ww.y0) * size_t(ww.width()) + size_t(x - ww.x0)];
        const float vb = crop.extra.at(name)[size_t(y - cw.y0) * size_t(cw.width()) + size_t(x - cw.x0)];
        ASSERT_EQ(0, std::memcmp(&va, &vb, sizeof va)) << name << " at " << x << "," << y;
      }
    }
}

TEST(PixelAccumulator, MeanVarianceAndRelativeError) {
  PixelAccumulator acc;
  EXPECT_TRUE(std::isinf(acc.relative_error(0.01)));
  for (float v : {1.f, 2.f, 3.f, 4.f}) acc.add(Vec3(v));
  const PixelEstimate e = acc.estimate();
  EXPECT_EQ(4u, e.spp);
  EXPECT_FLOAT_EQ(2.5f, e.mean.x);
  // Sample variance of 1..4 is 5/3; of the mean, 5/12. Grey: luminance = value (weights sum to 1). The unseen-event
  // term adds (mean / n)^2.
  EXPECT_NEAR(5.0 / 12.0, e.var_mean.y, 1e-6);
  EXPECT_NEAR(std::sqrt(5.0 / 12.0 + (2.5 / 4) * (2.5 / 4)) / 2.5, acc.relative_error(0.01), 1e-6);
  // Below the floor the error is measured against the floor.
  PixelAccumulator dark;
  for (float v : {0.f, 0.002f}) dark.add(Vec3(v));
  EXPECT_NEAR(std::sqrt(0.001 * 0.001 + 0.005 * 0.005) / 0.01, dark.relative_error(0.01), 1e-6);
  // Identical samples: the error is 1/n, never 0, so a pixel that saw nothing happen keeps sampling until n >= 1/E.
  PixelAccumulator flat;
  for (int i = 0; i < 8; ++i) flat.add(Vec3(0.f));
  EXPECT_NEAR(1.0 / 8, flat.relative_error(0.01), 1e-12);
}

TEST(PixelAccumulator, RoundsDoubleUpToTheCap) {
  EXPECT_EQ(32u, next_round(16, 1024));
  EXPECT_EQ(1000u, next_round(512, 1000));
  EXPECT_EQ(1000u, next_round(1000, 1000));
  EXPECT_EQ(48u, next_round(24, 48));
}

TEST(AdaptiveSampling, WholeRenderAndOddCropsAreBitwiseIdentical) {
  const Scene scene = penumbra_scene(41, 29);
  RenderOptions o;
  o.target_error = 0.2f;
  o.min_spp = 4;
  o.max_spp = 64;
  o.variance = true;
  o.tile_size = 16;
  const RenderResult whole = render(scene, o);
  const PixelWindow full{0, 0, 41, 29};
  for (const PixelWindow w : {PixelWindow{3, 5, 22, 18}, PixelWindow{0, 0, 1, 29}, PixelWindow{40, 28, 41, 29},
                              PixelWindow{7, 11, 38, 12}}) {
    RenderOptions oc = o;
    oc.window = w;
    oc.tile_size = 7;  // a different tiling too
    const RenderResult crop = render(scene, oc);
    expect_same_bits(whole.image, full, crop.image, w);
  }
  // The samples channel holds each pixel's own count, between the bounds, and varies over the picture: background
  // pixels (all samples zero) stop at the first round with n >= 1/E = 5, i.e. 8.
  const auto& spp = whole.image.extra.at("samples");
  const auto [lo, hi] = std::minmax_element(spp.begin(), spp.end());
  EXPECT_EQ(8.f, *lo);
  EXPECT_EQ(64.f, *hi);
}

// The same render without adaptive sampling is bitwise what render_pixel gives at the pixel's final count: the
// adaptive rounds only decide how many of the pixel's fixed sample sequence to take.
TEST(AdaptiveSampling, PixelsAreFixedSppRendersOfTheirOwnCount) {
  const Scene scene = penumbra_scene(41, 29);
  AdaptiveOptions a{0.05f, 4, 64, 0.01f};
  for (const auto& [x, y] : {std::pair{20, 20}, std::pair{5, 3}, std::pair{30, 25}}) {
    RayCounters c;
    const PixelEstimate e = render_pixel_adaptive(scene, x, y, 9, a, c);
    const PixelEstimate f = render_pixel(scene, x, y, 9, e.spp, c);
    EXPECT_EQ(0, std::memcmp(&e.mean, &f.mean, sizeof e.mean));
    EXPECT_EQ(0, std::memcmp(&e.var_mean, &f.var_mean, sizeof e.var_mean));
  }
}

// Statistical tests at full size: compiled into the main build only (a build that scales the randomised tests down,
// as the sanitizer builds do, would make them meaningless), so no build lists a test it then skips.
#if !defined(TESSERA_TEST_SCALE_DIVISOR) || TESSERA_TEST_SCALE_DIVISOR == 1

float lum(const Image& img, int x, int y) { return luminance(img.at(x, y)); }

// Per pixel, a render and an independent reference (different seed, more samples) differ by D = I - R with
// E[D^2] = Var(I) + Var(R) when both are unbiased; the sum over pixels has a standard deviation estimated from the
// pixels themselves (tests/support/test_error.h), so the tolerance comes from the data, plus a 20% margin.
testing::ErrorCheck error_check(const Scene& scene, uint32_t spp, uint32_t replicates) {
  RenderOptions o;
  o.variance = true;
  o.spp = spp;
  o.seed = 1;
  o.replicates = replicates;
  const RenderResult img = render(scene, o);
  o.spp = 16 * spp;
  o.seed = 2;
  const RenderResult ref = render(scene, o);
  const testing::ErrorCheck c = testing::compare_with_reference(img.image, ref.image);
  std::printf("%u spp, %u replicate(s): measured %.5g predicted %.5g (sd of measured %.2g), ratio %.3f\n", spp,
              replicates, c.measured, c.predicted, c.sd, c.measured / c.predicted);
  return c;
}

// With independent replicates the predicted variance is unbiased: the aggregate matches within 20%.
TEST(ErrorEstimates, ReplicatePredictionMatchesMeasuredErrorAgainstAnIndependentReference) {
  const Scene scene = penumbra_scene(48, 36);
  for (uint32_t k : {4u, 8u}) {
    const testing::ErrorCheck c = error_check(scene, 32, k);
    EXPECT_NEAR(c.measured, c.predicted, 0.2 * c.predicted + 3 * c.sd);
  }
}

// With one stratified sequence the i.i.d. estimate (sample variance / n) over-predicts: an upper bound, not a match.
TEST(ErrorEstimates, SingleSequencePredictionIsAConservativeBound) {
  const Scene scene = penumbra_scene(48, 36);
  const testing::ErrorCheck c = error_check(scene, 32, 1);
  EXPECT_LE(c.measured, c.predicted + 3 * c.sd);
}

TEST(AdaptiveSampling, HardPixelsGetMoreSamplesAndTheAchievedErrorIsNearTheTarget) {
  const int W = 48, H = 36;
  const Scene scene = penumbra_scene(W, H);
  RenderOptions o;
  o.target_error = 0.04f;
  o.min_spp = 32;
  o.max_spp = 1024;
  o.error_floor = 0.05f;
  o.variance = true;
  o.seed = 3;
  o.replicates = 8;
  const RenderResult ad = render(scene, o);
  RenderOptions r;
  r.spp = 2048;
  r.seed = 4;
  r.replicates = 8;
  r.variance = true;
  const RenderResult ref = render(scene, r);
  const auto& spp = ad.image.extra.at("samples");
  const auto& ref_var = ref.image.extra.at("variance.G");
  // Difficulty of a pixel: relative standard deviation of one sample, measured on the reference.
  std::vector<std::pair<double, size_t>> hardness;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t i = size_t(y) * W + size_t(x);
      const double sd1 = std::sqrt(double(ref_var[i]) * r.spp);
      hardness.push_back({sd1 / std::max(double(lum(ref.image, x, y)), double(o.error_floor)), i});
    }
  std::sort(hardness.begin(), hardness.end());
  const size_t n = hardness.size();
  double easy = 0, hard = 0;
  for (size_t k = 0; k < n / 4; ++k) easy += spp[hardness[k].second];
  for (size_t k = n - n / 4; k < n; ++k) hard += spp[hardness[k].second];
  easy /= double(n / 4);
  hard /= double(n / 4);
  std::printf("mean spp: easiest quarter %.1f, hardest quarter %.1f\n", easy, hard);
  EXPECT_GT(hard, 2 * easy);
  // Zero-variance pixels (background) stop after the first round.
  EXPECT_EQ(float(o.min_spp), spp[0]);

  // Achieved error of the pixels the rule stopped after more than one round (the first round's estimate was above
  // the target, the last one at or below it): sum of squared relative errors against the reference, minus the
  // reference's own (unbiased, replicate-estimated) share, compared with target^2 per pixel.
  double sum = 0, ref_share = 0, pred = 0;
  size_t m = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t i = size_t(y) * W + size_t(x);
      if (spp[i] >= float(o.max_spp) || spp[i] <= float(o.min_spp)) continue;
      const double den = std::max(double(lum(ref.image, x, y)), double(o.error_floor));
      const double d = (double(lum(ad.image, x, y)) - double(lum(ref.image, x, y))) / den;
      sum += d * d;
      ref_share += double(ref_var[i]) / (den * den);
      pred += double(ad.image.extra.at("variance.G")[i]) / (den * den);
      ++m;
    }
  const double achieved = std::sqrt(std::max(0.0, sum - ref_share) / double(m));
  std::printf("achieved relative error %.4f (target %.4f, predicted %.4f) over %zu pixels\n", achieved,
              double(o.target_error), std::sqrt(pred / double(m)), m);
  // Each such pixel's estimate was above E one round earlier, and doubling the samples halves the variance, so
  // in expectation its error lies between E / sqrt(2) and E; the mean square over m pixels has a relative standard
  // deviation of about sqrt(2 / m) (chi-square), i.e. sqrt(1 / (2 m)) on the root: three of those either side.
  const double tol = 3.0 * std::sqrt(1.0 / (2.0 * double(m)));
  ASSERT_GT(m, 50u);
  EXPECT_LE(achieved, o.target_error * (1.0 + tol));
  EXPECT_GE(achieved, o.target_error / std::sqrt(2.0) * (1.0 - tol));
}
#endif  // full-size statistical tests

}  // namespace
}  // namespace tessera
