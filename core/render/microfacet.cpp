#include "core/render/microfacet.h"
#include "core/util/exp_log.h"
#include "core/util/trig.h"

#include <algorithm>
#include <cmath>

namespace tessera {

namespace {

// tan^2(theta) x (cos^2(phi)/ax^2 + sin^2(phi)/ay^2) for a direction m, i.e. (m.x/ax)^2 + (m.y/ay)^2 over m.z^2.
float slope2(const Vec3& m, float ax, float ay) {
  const float x = m.x / ax, y = m.y / ay;
  return (x * x + y * y) / (m.z * m.z);
}

}  // namespace

float Beckmann::D(const Vec3& m) const {
  if (!(m.z > 0.f)) return 0.f;
  const float e = slope2(m, alpha_x, alpha_y);
  if (!std::isfinite(e)) return 0.f;
  const float c2 = m.z * m.z;
  return float(portable_exp(-double(e))) / (kPi * alpha_x * alpha_y * c2 * c2);
}

float Beckmann::lambda(const Vec3& w) const {
  const float c2 = w.z * w.z;
  const float s2 = std::max(0.f, 1.f - c2);
  if (s2 <= 0.f) return 0.f;
  // 1 / a = alpha along w's azimuth x tan(theta).
  const float t = std::sqrt(w.x * w.x * alpha_x * alpha_x + w.y * w.y * alpha_y * alpha_y) / std::abs(w.z);
  if (!(t > 0.f)) return 0.f;
  if (!std::isfinite(t)) return kInfinity;
  const double a = 1.0 / double(t);
  if (a > 8.0) return 0.f;  // erfc(8) ~ 1e-29: no masking at all
  return float(0.5 * (portable_erf(a) - 1.0) + portable_exp(-a * a) / (2.0 * a * std::sqrt(double(kPi))));
}

Vec3 Beckmann::sample_m(Vec2 u) const {
  // Azimuth: tan(phi) = (ay/ax) tan(2 pi u.y) (density proportional to 1/(cos^2/ax^2 + sin^2/ay^2)); then
  // tan^2(theta) = -log(1 - u.x) / (cos^2(phi)/ax^2 + sin^2(phi)/ay^2).
  const float t = 2.f * kPi * u.y;
  const SinCos st = portable_sincos(t);
  const float phi = portable_atan2(alpha_y * st.sin, alpha_x * st.cos);
  const SinCos sc = portable_sincos(phi);
  const float cp = sc.cos, sp = sc.sin;
  const float a_inv2 = cp * cp / (alpha_x * alpha_x) + sp * sp / (alpha_y * alpha_y);
  const float tan2 = -float(portable_log1p(-double(u.x))) / a_inv2;
  const float cos_t = 1.f / std::sqrt(1.f + tan2);
  const float sin_t = std::sqrt(tan2) * cos_t;  // not sqrt(1 - cos^2): at alpha 1e-4 that rounds to 0
  return {sin_t * cp, sin_t * sp, cos_t};
}

}  // namespace tessera
