#include "core/render/fresnel.h"

#include <algorithm>
#include <cmath>

namespace tessera {

float fresnel_dielectric(float cos_i, float eta) {
  cos_i = std::clamp(cos_i, -1.f, 1.f);
  if (cos_i < 0.f) {  // arriving from the inside: swap the media
    eta = 1.f / eta;
    cos_i = -cos_i;
  }
  const float sin2_i = std::max(0.f, 1.f - cos_i * cos_i);
  const float sin2_t = sin2_i / (eta * eta);
  if (sin2_t >= 1.f) return 1.f;
  const float cos_t = std::sqrt(std::max(0.f, 1.f - sin2_t));
  const float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return 0.5f * (r_par * r_par + r_perp * r_perp);
}

namespace {

// One channel, in double precision: the terms cancel strongly for small k and grazing angles.
float conductor_channel(double cos_i, double eta, double k) {
  const double c2 = cos_i * cos_i, s2 = 1.0 - c2;
  const double t0 = eta * eta - k * k - s2;
  const double a2b2 = std::sqrt(std::max(0.0, t0 * t0 + 4.0 * eta * eta * k * k));
  const double a = std::sqrt(std::max(0.0, 0.5 * (a2b2 + t0)));
  const double t1 = a2b2 + c2, t2 = 2.0 * cos_i * a;
  const double rs = (t1 + t2) > 0.0 ? (t1 - t2) / (t1 + t2) : 1.0;
  const double t3 = c2 * a2b2 + s2 * s2, t4 = t2 * s2;
  const double rp = rs * ((t3 + t4) > 0.0 ? (t3 - t4) / (t3 + t4) : 1.0);
  return float(std::clamp(0.5 * (rs + rp), 0.0, 1.0));
}

}  // namespace

Vec3 fresnel_conductor(float cos_i, const Vec3& eta, const Vec3& k) {
  const double c = std::min(1.0, std::abs(double(cos_i)));
  return {conductor_channel(c, eta.x, k.x), conductor_channel(c, eta.y, k.y), conductor_channel(c, eta.z, k.z)};
}

}  // namespace tessera
