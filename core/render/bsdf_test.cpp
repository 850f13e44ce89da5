// BSDF tests: Fresnel closed forms; the Beckmann distribution's normalisations; chi-square goodness of fit of
// sample() against pdf() for diffuse and rough conductor BSDFs from alpha 1e-4 to 0.5 and incident angles down to
// grazing; reciprocity; sample weights equal to their closed forms; the conductor's white furnace (F = 1) matching
// its single-scattering albedo (computed by quadrature); glass's Fresnel split, tints, Snell's law and total internal reflection.
#include "core/render/bsdf.h"

#include "tests/support/chi_square.h"
#include "core/render/fresnel.h"
#include "tests/support/test_scale.h"

#include <gtest/gtest.h>

#include <random>

namespace tessera {
namespace {

using glm::dvec2;
using glm::dvec3;

const Vec3 kUp(0.f, 0.f, 1.f);

Vec3 from_angles(double theta_deg, double phi_deg) {
  const double t = theta_deg * kPi / 180.0, p = phi_deg * kPi / 180.0;
  return Vec3(float(std::sin(t) * std::cos(p)), float(std::sin(t) * std::sin(p)), float(std::cos(t)));
}

Material conductor(float ax, float ay, Vec3 eta_t = Vec3(0.2f, 0.9f, 1.1f), Vec3 k = Vec3(3.9f, 2.4f, 2.2f)) {
  Material m;
  m.kind = MaterialKind::kRoughConductor;
  m.alpha_x = ax;
  m.alpha_y = ay;
  m.eta_t = eta_t;
  m.k = k;
  return m;
}

Material diffuse(bool twosided = false) {
  Material m;
  m.kind = MaterialKind::kDiffuse;
  m.twosided = twosided;
  return m;
}

// Microfacet normal at chart point (x, y): s = tan(theta_m) / alpha = x / (1 - x), phi_m = 2 pi y; *jac is
// |d omega_m / dx dy|. Linear in s near the normal, so cells resolve the lobe and its cut by the horizon at any alpha.
dvec3 normal_at(double x, double y, double alpha, double* jac) {
  const double s = x / (1.0 - x), phi = 2.0 * kPi * y;
  const double q = std::sqrt(1.0 + alpha * alpha * s * s);
  // sin(theta) dtheta = alpha^2 s / q^3 ds, ds = dx / (1 - x)^2.
  *jac = alpha * alpha * s / (q * q * q) / ((1.0 - x) * (1.0 - x)) * 2.0 * kPi;
  return {alpha * s / q * std::cos(phi), alpha * s / q * std::sin(phi), 1.0 / q};
}

// The chart of reflected directions by their half vector (normal_at), for outgoing direction wo.
testing::DirectionChart half_vector_chart(const dvec3& wo, double alpha) {
  testing::DirectionChart c;
  c.to_dir = [wo, alpha](double x, double y) -> std::optional<std::pair<dvec3, double>> {
    double jac;
    const dvec3 m = normal_at(x, y, alpha, &jac);
    const double om = glm::dot(wo, m);
    if (om <= 0.0) return std::nullopt;
    return std::make_pair(2.0 * om * m - wo, 4.0 * om * jac);  // d omega_i = 4 (wo.m) d omega_m
  };
  c.from_dir = [wo, alpha](const dvec3& wi) -> std::optional<dvec2> {
    const dvec3 m = glm::normalize(wo + wi);
    const double s = std::sqrt(m.x * m.x + m.y * m.y) / m.z / alpha;
    double phi = std::atan2(m.y, m.x);
    if (phi < 0.0) phi += 2.0 * kPi;
    return dvec2(s / (1.0 + s), phi / (2.0 * kPi));
  };
  return c;
}

// The upper hemisphere by (cos theta, phi / 2 pi).
testing::DirectionChart hemisphere_chart() {
  testing::DirectionChart c;
  c.to_dir = [](double x, double y) -> std::optional<std::pair<dvec3, double>> {
    const double st = std::sqrt(std::max(0.0, 1.0 - x * x)), phi = 2.0 * kPi * y;
    return std::make_pair(dvec3(st * std::cos(phi), st * std::sin(phi), x), 2.0 * kPi);
  };
  c.from_dir = [](const dvec3& w) -> std::optional<dvec2> {
    if (w.z <= 0.0) return std::nullopt;
    double phi = std::atan2(w.y, w.x);
    if (phi < 0.0) phi += 2.0 * kPi;
    return dvec2(w.z, phi / (2.0 * kPi));
  };
  return c;
}

// Runs the chi-square test of bsdf's sampling for wo; fails below a Bonferroni-corrected 1% level over `tests`.
void expect_sampling_matches_pdf(const Bsdf& bsdf, const Vec3& wo, const testing::DirectionChart& chart, int tests,
                                 const std::string& what) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  const int n = int(testing::scaled(200000));
  const auto r = testing::chi_square_test(
      chart, [&](const dvec3& wi) { return double(bsdf.pdf(wo, Vec3(glm::normalize(wi)))); },
      [&]() -> std::optional<dvec3> {
        const float uc = U(rng);
        const Vec2 u(U(rng), U(rng));
        const auto s = bsdf.sample(wo, uc, u);
        if (!s) return std::nullopt;
        return dvec3(s->wi);
      },
      n, 12, 24, 16);
  EXPECT_TRUE(r.message.empty()) << what << ": " << r.message;
  EXPECT_GT(r.p_value, 0.01 / tests) << what << ": chi^2 " << r.statistic << " with " << r.dof << " degrees of freedom";
}

TEST(Fresnel, DielectricClosedForms) {
  EXPECT_NEAR(fresnel_dielectric(1.f, 1.5f), 0.04f, 1e-6f);    // ((1.5-1)/(1.5+1))^2
  EXPECT_NEAR(fresnel_dielectric(-1.f, 1.5f), 0.04f, 1e-6f);   // the same from inside
  EXPECT_FLOAT_EQ(fresnel_dielectric(0.f, 1.5f), 1.f);         // grazing
  EXPECT_FLOAT_EQ(fresnel_dielectric(1.f, 1.f), 0.f);          // index-matched
  // Inside, beyond the critical angle asin(1/1.5) = 41.8 degrees: total internal reflection.
  EXPECT_FLOAT_EQ(fresnel_dielectric(-std::cos(0.75f), 1.5f), 1.f);
  EXPECT_LT(fresnel_dielectric(-std::cos(0.70f), 1.5f), 1.f);
}

TEST(Fresnel, ConductorClosedForms) {
  // Normal incidence: ((n-1)^2 + k^2) / ((n+1)^2 + k^2).
  const Vec3 eta(0.2f, 0.9f, 1.1f), k(3.9f, 2.4f, 2.2f);
  const Vec3 F = fresnel_conductor(1.f, eta, k);
  for (int c = 0; c < 3; ++c) {
    const double n = eta[c], kk = k[c];
    EXPECT_NEAR(F[c], ((n - 1) * (n - 1) + kk * kk) / ((n + 1) * (n + 1) + kk * kk), 1e-6) << c;
  }
  // k = 0 is a dielectric seen from outside; eta = k = 0 reflects everything.
  for (float cosv : {1.f, 0.8f, 0.3f, 0.05f}) {
    EXPECT_NEAR(fresnel_conductor(cosv, Vec3(1.5f), Vec3(0.f)).x, fresnel_dielectric(cosv, 1.5f), 1e-6f) << cosv;
    EXPECT_FLOAT_EQ(fresnel_conductor(cosv, Vec3(0.f), Vec3(0.f)).y, 1.f) << cosv;
  }
  EXPECT_FLOAT_EQ(fresnel_conductor(0.f, eta, k).x, 1.f);  // grazing
}

// Integral of g(m) over microfacet normals (midpoints of an n x n grid on normal_at's chart).
double integrate_normals(double alpha, const std::function<double(const dvec3& m)>& g, int n = 400) {
  double sum = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      double jac;
      const dvec3 m = normal_at((i + 0.5) / n, (j + 0.5) / n, alpha, &jac);
      sum += g(m) * jac;
    }
  return sum / (double(n) * n);
}

TEST(Beckmann, ProjectedAreaAndVisibleNormalsIntegrateToOne) {
  for (double alpha : {1e-4, 1e-2, 0.1, 0.3, 0.5}) {
    for (double ratio : {1.0, 0.5}) {
      const Beckmann b{float(alpha), float(alpha * ratio)};
      const double a = alpha;  // the larger alpha: the chart's integrand stays bounded
      // Integral of D(m) cos(theta_m) = 1.
      EXPECT_NEAR(integrate_normals(a, [&](const dvec3& m) { return b.D(Vec3(m)) * m.z; }), 1.0, 2e-3) << alpha;
      // Integral of G1(wo) max(0, wo.m) D(m) = cos(theta_o) (Smith's visible normals are normalised).
      for (double th : {0.0, 45.0, 75.0, 85.0}) {
        const dvec3 wo(from_angles(th, 30.0));
        const double v = integrate_normals(a, [&](const dvec3& m) {
          return b.G1(Vec3(wo)) * std::max(0.0, glm::dot(wo, m)) * b.D(Vec3(m));
        });
        EXPECT_NEAR(v / wo.z, 1.0, 1e-2) << "alpha " << alpha << " theta " << th;
      }
    }
  }
}

TEST(Bsdf, DiffuseSamplingMatchesPdf) {
  const Material m = diffuse();
  const Bsdf bsdf(m, kUp, kUp, Vec3(0.7f));
  for (double th : {0.0, 60.0, 89.0}) expect_sampling_matches_pdf(bsdf, from_angles(th, 10.0), hemisphere_chart(), 3, "diffuse");
}

TEST(Bsdf, RoughConductorSamplingMatchesPdf) {
  const double alphas[][2] = {{1e-4, 1e-4}, {1e-3, 1e-3}, {0.01, 0.01}, {0.1, 0.1}, {0.3, 0.3}, {0.5, 0.5}, {0.05, 0.3}, {0.5, 0.1}};
  const double thetas[] = {0.0, 30.0, 60.0, 80.0, 89.0};
  const int tests = int(std::size(alphas) * std::size(thetas));
  for (const auto& a : alphas) {
    const Material m = conductor(float(a[0]), float(a[1]));
    const Bsdf bsdf(m, kUp, kUp, Vec3(1.f));
    for (double th : thetas) {
      // At alpha 1e-4 and 89 degrees the lobe is 3.5e-6 radians wide across the plane of incidence: ~60 float ulps
      // of a direction's components, so quantisation of the float directions themselves shows in the test.
      if (a[0] < 1e-3 && th > 85.0) continue;
      const Vec3 wo = from_angles(th, 25.0);
      expect_sampling_matches_pdf(bsdf, wo, half_vector_chart(dvec3(wo), std::max(a[0], a[1])), tests,
                                  "alpha " + std::to_string(a[0]) + "/" + std::to_string(a[1]) + " theta " + std::to_string(th));
    }
  }
}

TEST(Bsdf, ReciprocityAndSampleWeights) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  for (const Material& m : {diffuse(), conductor(0.2f, 0.2f), conductor(0.05f, 0.4f), conductor(1e-3f, 1e-3f)}) {
    const Bsdf bsdf(m, kUp, kUp, Vec3(0.8f, 0.6f, 0.4f));
    for (int k = 0; k < int(testing::scaled(2000)); ++k) {
      const Vec3 wo = sample_cosine_hemisphere(Vec2(U(rng), U(rng)));
      const Vec3 wi = sample_cosine_hemisphere(Vec2(U(rng), U(rng)));
      const Vec3 a = bsdf.f(wo, wi), b = bsdf.f(wi, wo);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-4f * std::max(1.f, a[c])) << "reciprocity";
      const auto s = bsdf.sample(wo, U(rng), Vec2(U(rng), U(rng)));
      if (!s) continue;
      EXPECT_FALSE(s->delta);
      const Vec3 w = s->f * s->wi.z / s->pdf;
      Vec3 expect;
      if (m.kind == MaterialKind::kDiffuse) {
        expect = Vec3(0.8f, 0.6f, 0.4f);  // cosine sampling: weight = albedo
      } else {
        // Normal-distribution sampling: weight = F G |wo.m| / (cos_o cos_m).
        const Vec3 mm = glm::normalize(wo + s->wi);
        const Beckmann be{m.alpha_x, m.alpha_y};
        expect = Vec3(0.8f, 0.6f, 0.4f) * fresnel_conductor(glm::dot(wo, mm), m.eta_t, m.k) *
                 (be.G(wo, s->wi) * glm::dot(wo, mm) / (wo.z * mm.z));
      }
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(w[c], expect[c], 2e-3f * std::max(1.f, expect[c])) << "weight";
    }
  }
}

TEST(Bsdf, DiffuseIsOneSidedUnlessTwosided) {
  const Vec3 below(0.f, 0.f, -1.f), wi = glm::normalize(Vec3(0.3f, 0.f, -1.f));
  EXPECT_EQ(Bsdf(diffuse(false), kUp, kUp, Vec3(1.f)).f(below, wi), Vec3(0.f));
  EXPECT_FALSE(Bsdf(diffuse(false), kUp, kUp, Vec3(1.f)).sample(below, 0.5f, Vec2(0.5f)).has_value());
  EXPECT_GT(Bsdf(diffuse(true), kUp, kUp, Vec3(1.f)).f(below, wi).x, 0.f);
  // Never through the surface.
  EXPECT_EQ(Bsdf(diffuse(true), kUp, kUp, Vec3(1.f)).f(kUp, wi), Vec3(0.f));
}

TEST(Bsdf, RoughConductorWhiteFurnaceLosesOnlyTheSingleScatteringShadowing) {
  // F = 1 (eta = k = 0): the albedo is the single-scattering albedo integral of D G / (4 cos_o) over wi; sampling
  // must reproduce it, it never exceeds 1, and it tends to 1 as alpha -> 0.
  for (double alpha : {1e-4, 0.01, 0.1, 0.3, 0.5}) {
    const Material m = conductor(float(alpha), float(alpha), Vec3(0.f), Vec3(0.f));
    const Bsdf bsdf(m, kUp, kUp, Vec3(1.f));
    for (double th : {0.0, 45.0, 70.0, 85.0}) {
      const Vec3 wo = from_angles(th, 0.0);
      const auto chart = half_vector_chart(dvec3(wo), alpha);
      double quad = 0.0;
      const int q = 300;
      for (int j = 0; j < q; ++j)
        for (int i = 0; i < q; ++i)
          if (const auto d = chart.to_dir((i + 0.5) / q, (j + 0.5) / q)) {
            const Vec3 wi(glm::normalize(d->first));
            if (wi.z > 0.f) quad += double(bsdf.f(wo, wi).x) * wi.z * d->second;
          }
      quad /= double(q) * q;
      std::mt19937 rng(3);
      std::uniform_real_distribution<float> U(0.f, 1.f);
      double sum = 0.0, sum2 = 0.0;
      const int n = int(testing::scaled(100000));
      for (int k = 0; k < n; ++k) {
        const auto s = bsdf.sample(wo, U(rng), Vec2(U(rng), U(rng)));
        const double w = s ? double(s->f.x * s->wi.z / s->pdf) : 0.0;
        sum += w;
        sum2 += w * w;
      }
      const double mean = sum / n, se = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
      EXPECT_LE(quad, 1.0 + 1e-3) << alpha << " " << th;
      EXPECT_NEAR(mean, quad, 5.0 * se + 2e-3) << "alpha " << alpha << " theta " << th;
      if (alpha <= 0.01) {
        EXPECT_GT(mean, th < 80.0 ? 0.999 : 0.99) << "alpha " << alpha << " theta " << th;
      }
      if (th == 0.0) {
        EXPECT_GT(mean, 1.0 - 0.15 * alpha) << alpha;  // Beckmann at normal incidence: 5.9% lost at alpha 0.5
      }  // Beckmann at normal incidence loses a few percent at most
    }
  }
}

TEST(Bsdf, GlassSplitsByFresnelWithTints) {
  Material m;
  m.kind = MaterialKind::kGlass;
  m.eta = 1.5f;
  m.reflect_tint = Vec3(0.9f, 0.8f, 0.7f);
  m.transmit_tint = Vec3(0.5f, 0.6f, 0.7f);
  const Bsdf bsdf(m, kUp, kUp, Vec3(1.f));
  EXPECT_TRUE(bsdf.delta());
  for (double th : {0.0, 40.0, 70.0, 88.0}) {
    const Vec3 wo = from_angles(th, 0.0);
    const float F = fresnel_dielectric(wo.z, 1.5f);
    int reflected = 0;
    const int n = 20000;
    for (int k = 0; k < n; ++k) {
      const auto s = bsdf.sample(wo, (k + 0.5f) / n, Vec2(0.5f));
      ASSERT_TRUE(s);
      EXPECT_TRUE(s->delta);
      const Vec3 w = s->f * std::abs(s->wi.z) / s->pdf;
      if (s->wi.z > 0.f) {
        ++reflected;
        EXPECT_NEAR(glm::length(s->wi - Vec3(-wo.x, -wo.y, wo.z)), 0.f, 1e-5f);
        EXPECT_NEAR(glm::length(w - m.reflect_tint), 0.f, 1e-4f);
      } else {
        EXPECT_NEAR(std::sqrt(1.f - s->wi.z * s->wi.z) * 1.5f, std::sqrt(1.f - wo.z * wo.z), 1e-4f);  // Snell
        EXPECT_NEAR(glm::length(w - m.transmit_tint), 0.f, 1e-4f);
      }
    }
    EXPECT_NEAR(double(reflected) / n, F, 1.0 / n + 1e-4) << th;  // stratified uc: the split is F up to one sample
  }
  // From inside beyond the critical angle: always reflected.
  const Vec3 inside(std::sin(1.f), 0.f, -std::cos(1.f));
  for (float uc : {0.f, 0.5f, 0.999f}) {
    const auto s = bsdf.sample(inside, uc, Vec2(0.5f));
    ASSERT_TRUE(s);
    EXPECT_LT(s->wi.z, 0.f);
    EXPECT_NEAR(glm::length(s->f * std::abs(s->wi.z) / s->pdf - m.reflect_tint), 0.f, 1e-4f);
  }
}

}  // namespace
}  // namespace tessera
