// Sample warps: the linear warp inverts its CDF exactly, the bilinear-marginals warp follows its density (Pearson's
// chi-square, as pbrt tests its warps) and equals the bilinear density for rank-one weights, and the spherical
// rectangle's inverse map undoes its sample map.
#include "core/sampling/sampling.h"

#include "tests/support/chi_square.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <vector>

namespace tessera {
namespace {

using glm::dvec2;
using glm::dvec3;

TEST(LinearWarp, InvertsItsCdf) {
  for (const auto& [a, b] : {std::pair{1.f, 1.f}, {0.f, 1.f}, {1.f, 0.f}, {0.2f, 3.f}, {5.f, 0.01f}}) {
    double integral = 0;
    for (int k = 0; k < 1000; ++k) {
      const float u = (float(k) + 0.5f) / 1000.f;
      const double x = sample_linear(u, a, b);
      // CDF (a x + (b - a) x^2 / 2) / ((a + b) / 2), in double.
      const double cdf = (a * x + (b - a) * x * x / 2) / ((double(a) + b) / 2);
      EXPECT_NEAR(cdf, u, 2e-6) << a << " " << b << " u " << u;
      EXPECT_GE(x, 0.0);
      EXPECT_LT(x, 1.0);
      integral += linear_pdf(u, a, b) / 1000.0;  // midpoint rule, exact for a linear density
    }
    EXPECT_NEAR(integral, 1.0, 1e-5) << a << " " << b;
  }
  EXPECT_EQ(sample_linear(0.f, 0.f, 1.f), 0.f);
  EXPECT_LT(sample_linear(0x1.fffffep-1f, 1.f, 0.f), 1.f);
}

// The unit square as a chart for chi_square_test: the "direction" is (x, y, 0), the Jacobian 1.
testing::DirectionChart square_chart() {
  testing::DirectionChart c;
  c.to_dir = [](double x, double y) -> std::optional<std::pair<dvec3, double>> { return std::make_pair(dvec3(x, y, 0), 1.0); };
  c.from_dir = [](const dvec3& w) -> std::optional<dvec2> { return dvec2(w.x, w.y); };
  return c;
}

TEST(BilinearMarginalsWarp, FollowsItsDensity) {
  const std::array<std::array<float, 4>, 4> cases = {{{1.f, 1.f, 1.f, 1.f},
                                                       {0.01f, 1.f, 0.3f, 0.05f},
                                                       {1.f, 0.f, 0.f, 0.f},
                                                       {0.2f, 0.9f, 2.5f, 0.7f}}};
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  for (const auto& w : cases) {
    const int n = int(testing::scaled(200000));
    const auto r = testing::chi_square_test(
        square_chart(), [&](const dvec3& p) { return double(bilinear_marginals_pdf(Vec2(p.x, p.y), w)); },
        [&]() -> std::optional<dvec3> {
          const WarpSample s = sample_bilinear_marginals(Vec2(U(rng), U(rng)), w);
          EXPECT_FLOAT_EQ(s.pdf, bilinear_marginals_pdf(s.p, w));
          return dvec3(s.p.x, s.p.y, 0.0);
        },
        n, 16, 16);
    EXPECT_TRUE(r.message.empty()) << r.message;
    EXPECT_GT(r.p_value, 0.01 / double(cases.size())) << "chi^2 " << r.statistic << " with " << r.dof << " dof";
    // The density integrates to 1 (midpoint rule; the density is bilinear, so exact).
    double integral = 0;
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i) integral += bilinear_marginals_pdf(Vec2((i + 0.5f) / 64, (j + 0.5f) / 64), w) / 4096.0;
    EXPECT_NEAR(integral, 1.0, 1e-5);
  }
}

TEST(BilinearMarginalsWarp, EqualsTheBilinearDensityForRankOneWeights) {
  // w(1,1) w(0,0) = w(1,0) w(0,1): the bilinear interpolation is a product of linear functions, i.e. its marginals'.
  const std::array<float, 4> w = {1.f, 2.f, 3.f, 6.f};
  for (float x : {0.f, 0.3f, 0.9f})
    for (float y : {0.f, 0.5f, 0.99f}) {
      const float bilinear = (1 - x) * (1 - y) * w[0] + x * (1 - y) * w[1] + (1 - x) * y * w[2] + x * y * w[3];
      EXPECT_NEAR(bilinear_marginals_pdf(Vec2(x, y), w), 4.f * bilinear / 12.f, 1e-5f) << x << "," << y;
    }
}

TEST(SphericalRectangleSampling, InvertUndoesSample) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  struct Case {
    Vec3 o, corner, ex, ey;
  };
  for (const Case& c : {Case{Vec3(0.f), Vec3(-0.5f, 1.f, -0.5f), Vec3(1.f, 0.f, 0.f), Vec3(0.f, 0.f, 1.f)},
                        Case{Vec3(2.f, 0.1f, -1.f), Vec3(-0.9f, 1.98f, -0.9f), Vec3(1.8f, 0.f, 0.f), Vec3(0.f, 0.f, 1.8f)},
                        Case{Vec3(0.3f, 1.9f, 0.2f), Vec3(-0.25f, 1.98f, -0.2f), Vec3(0.5f, 0.f, 0.f), Vec3(0.f, 0.f, 0.4f)}}) {
    SphericalRectangle sr;
    ASSERT_TRUE(sr.init(c.o, c.corner, c.ex, c.ey));
    for (int k = 0; k < 1000; ++k) {
      const Vec2 u(U(rng), U(rng));
      const Vec2 back = sr.invert(sr.sample(u).p);
      EXPECT_NEAR(back.x, u.x, 2e-3f) << k;
      EXPECT_NEAR(back.y, u.y, 2e-3f) << k;
    }
  }
}

TEST(SphericalRectangleSampling, CornersComeFirstAndCosinesFollowThem) {
  const Vec3 o(0.2f, 0.f, 0.1f), corner(-0.5f, 1.f, -0.5f), ex(1.f, 0.f, 0.f), ey(0.f, 0.f, 1.f);
  SphericalRectangle sr;
  ASSERT_TRUE(sr.init(o, corner, ex, ey));
  const Vec3 corners[4] = {corner, corner + ex, corner + ey, corner + ex + ey};
  const Vec2 us[4] = {{0.f, 0.f}, {1.f, 0.f}, {0.f, 1.f}, {1.f, 1.f}};
  const Vec3 n = glm::normalize(Vec3(0.3f, 1.f, -0.2f));
  const std::array<float, 4> cosines = sr.corner_cosines(n);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(glm::length(sr.sample(us[i]).p - corners[i]), 0.f, 1e-4f) << i;
    EXPECT_NEAR(cosines[size_t(i)], glm::dot(n, glm::normalize(corners[i] - o)), 1e-6f) << i;
  }
}

// The guided search of Distribution1D finds exactly the bin a binary search over its whole cdf finds, for every u
// (bucket edges, cdf entries and their neighbours, random values) and for tables with empty runs and spikes.
TEST(Distribution1D, GuidedSearchIsTheWholeSearch) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  for (int trial = 0; trial < 40; ++trial) {
    const int n = 16 + int(rng() % 700);
    std::vector<float> w(size_t(n), 0.f);
    for (int i = 0; i < n; ++i) {
      const uint32_t r = rng() % 10;
      w[size_t(i)] = r < 4 ? 0.f : (r == 9 ? 1e4f * U(rng) : U(rng));  // empty runs, spikes
    }
    const Distribution1D d(w);
    // The reference: the cdf as the constructor builds it, searched whole.
    std::vector<float> cdf(size_t(n) + 1, 0.f);
    double acc = 0.0;
    for (int i = 0; i < n; ++i) cdf[size_t(i) + 1] = float(acc += double(w[size_t(i)]) / double(n));
    for (int i = 1; i <= n; ++i) cdf[size_t(i)] = float(double(cdf[size_t(i)]) / acc);
    cdf[size_t(n)] = 1.f;
    std::vector<float> us;
    for (int b = 0; b <= n; ++b) {
      const float t = float(b) / float(n);
      us.insert(us.end(), {t, std::nextafter(t, 0.f), std::nextafter(t, 1.f)});
    }
    for (const float c : cdf) us.insert(us.end(), {c, std::nextafter(c, 0.f), std::nextafter(c, 1.f)});
    for (int i = 0; i < 2000; ++i) us.push_back(U(rng));
    for (const float u : us) {
      if (!(u >= 0.f && u < 1.f)) continue;
      int i = std::clamp(int(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()) - 1, 0, n - 1);
      while (i < n - 1 && w[size_t(i)] == 0.f) ++i;
      int bin = -1;
      float pdf = 0.f;
      d.sample(u, &pdf, &bin);
      ASSERT_EQ(i, bin) << "n " << n << " u " << u;
    }
  }
}

// Distribution2D::pdf is bitwise the product of its marginal's and its row's densities, as sample() reports them.
TEST(Distribution2D, PdfIsTheSampledDensity) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  const int w = 64, h = 32;
  std::vector<float> wt(size_t(w * h));
  for (float& v : wt) v = U(rng) < 0.3f ? 0.f : U(rng);
  const Distribution2D d(wt, w, h);
  for (int i = 0; i < 20000; ++i) {
    float pdf = 0.f;
    const Vec2 uv = d.sample(Vec2(U(rng), U(rng)), &pdf);
    ASSERT_EQ(std::bit_cast<uint32_t>(pdf), std::bit_cast<uint32_t>(d.pdf(uv)));
  }
}

}  // namespace
}  // namespace tessera
