// Integrator unit tests: refraction obeys Snell's law in both directions (n points outside, eta = n_in / n_out),
// total internal reflection is reported at grazing angles inside the denser medium, and reflection mirrors.
#include "core/render/integrator.h"

#include "core/sampling/sampling.h"

#include <gtest/gtest.h>

#include <random>

namespace tessera {
namespace {

struct RandomDirs {
  std::mt19937 rng{11};
  std::uniform_real_distribution<float> U{0.f, 1.f};
  Vec3 dir() { return sample_uniform_sphere(Vec2(U(rng), U(rng))); }
};

TEST(Refract, SnellsLawEnteringAndLeaving) {
  RandomDirs r;
  for (float eta : {1.5f, 1.33f, 0.7f, 2.4f}) {
    for (int k = 0; k < 2000; ++k) {
      const Vec3 n = r.dir();
      const Vec3 w = r.dir();
      const float cos_w = glm::dot(w, n);
      if (std::abs(cos_w) < 1e-3f) continue;
      const bool entering = cos_w > 0.f;
      // Index of the side w lies on, and of the other side.
      const float n_w = entering ? 1.f : eta, n_t = entering ? eta : 1.f;
      const float sin_w = glm::length(glm::cross(w, n));
      Vec3 wt;
      const bool ok = refract(w, n, eta, &wt);
      if (n_w / n_t * sin_w >= 1.f + 1e-5f) {
        EXPECT_FALSE(ok) << "eta " << eta << " sin " << sin_w;
        continue;
      }
      if (n_w / n_t * sin_w > 1.f - 1e-5f) continue;  // too close to the critical angle to call
      ASSERT_TRUE(ok) << "eta " << eta;
      EXPECT_NEAR(glm::length(wt), 1.f, 1e-5f);
      EXPECT_LT(glm::dot(wt, n) * cos_w, 0.f) << "the transmitted ray must cross to the other side";
      EXPECT_NEAR(n_w * sin_w, n_t * glm::length(glm::cross(wt, n)), 2e-5f) << "Snell's law";
      // Coplanar with w and n, tangential part on the opposite side of the normal from w's (w points away).
      const Vec3 tw = w - cos_w * n, tt = wt - glm::dot(wt, n) * n;
      EXPECT_NEAR(glm::length(tt + (n_w / n_t) * tw), 0.f, 2e-5f);
    }
  }
}

TEST(Refract, TotalInternalReflectionAtGrazingAngleInside) {
  // Inside glass (eta 1.5) the critical angle is asin(1/1.5) = 41.8 degrees: 80 degrees from the inner normal fails,
  // 30 degrees refracts out.
  const Vec3 n(0.f, 0.f, 1.f);
  auto inside = [&](float deg) {
    const float a = deg * kPi / 180.f;
    return Vec3(std::sin(a), 0.f, -std::cos(a));  // w points away from the surface, into the glass
  };
  Vec3 wt(0.f);
  EXPECT_FALSE(refract(inside(80.f), n, 1.5f, &wt));
  EXPECT_FALSE(refract(inside(42.f), n, 1.5f, &wt));
  EXPECT_TRUE(refract(inside(41.f), n, 1.5f, &wt));
  EXPECT_TRUE(refract(inside(30.f), n, 1.5f, &wt));
  EXPECT_NEAR(wt.z, std::cos(std::asin(1.5f * 0.5f)), 1e-6f);
  // From outside there is never total internal reflection, even at grazing incidence.
  EXPECT_TRUE(refract(Vec3(std::sin(1.55f), 0.f, std::cos(1.55f)), n, 1.5f, &wt));
}

TEST(Refract, IndexOneLeavesDirectionsUnchanged) {
  RandomDirs r;
  for (int k = 0; k < 1000; ++k) {
    const Vec3 n = r.dir(), w = r.dir();
    const float c = std::abs(glm::dot(w, n));
    if (c < 1e-3f) continue;
    Vec3 wt;
    ASSERT_TRUE(refract(w, n, 1.f, &wt));
    // cos_t = sqrt(1 - (1 - cos^2)) is off by about eps / (2 cos) after rounding; a few ulps besides.
    EXPECT_NEAR(glm::length(wt + w), 0.f, 4e-6f + 2.f * kMachineEpsilon / c);
  }
}

TEST(Reflect, MirrorsAboutTheNormalEitherOrientation) {
  const Vec3 w = glm::normalize(Vec3(0.3f, -0.2f, 0.9f));
  const Vec3 n(0.f, 0.f, 1.f);
  EXPECT_NEAR(glm::length(reflect(w, n) - Vec3(-w.x, -w.y, w.z)), 0.f, 1e-6f);
  EXPECT_NEAR(glm::length(reflect(w, -n) - reflect(w, n)), 0.f, 1e-6f);
}

}  // namespace
}  // namespace tessera
