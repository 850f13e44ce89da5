#include "core/render/light.h"
#include "core/util/trig.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <tbb/parallel_for.h>

namespace tessera {

void AreaLight::finish() {
  std::vector<float> areas;
  for (const auto& r : rects) areas.push_back(r.area);
  for (const auto& t : tris) areas.push_back(t.area);
  total_area = 0.f;
  for (float a : areas) total_area += a;
  if (sphere) total_area = 4.f * kPi * sphere->radius * sphere->radius;
  part_by_area = Distribution1D(areas);
}

namespace {

// The point corner + a ex + b ey, rounded once from double precision: within half an ulp per axis of the exact
// parallelogram's plane, whatever the coordinates' magnitude (a float expression at 1e5 may stray several ulps).
Vec3 on_plane(const Vec3& corner, const Vec3& ex, const Vec3& ey, double a, double b) {
  return Vec3(Vec3d(corner) + a * Vec3d(ex) + b * Vec3d(ey));
}

// Error bound of a point rounded once from an exact value (one ulp per axis, twice the half-ulp for safety).
Vec3 rounded_once_error(const Vec3& p) { return 2.f * kMachineEpsilon * glm::abs(p); }

// Converts an area-measure sample at q (normal nq, area pdf pdf_a) into a solid-angle sample seen from p.
// The difference p - q is taken in double precision: exact for the two float points, so far from the origin (1e5,
// where a float difference of points a unit apart keeps only ~7 bits after the point) the distance and the cosine
// at a grazing light stay accurate.
LightSample from_area(const Vec3& p, const Vec3& q, const Vec3& nq, float pdf_a, const Vec3& radiance) {
  const Vec3d w = Vec3d(p) - Vec3d(q);
  const double d2 = glm::dot(w, w);
  const double cos_l = glm::dot(Vec3d(nq), w) / std::sqrt(d2);
  if (!(cos_l > 0.0) || !(d2 > 0.0)) return {q, nq, Vec3(0.f), 0.f};
  return {q, nq, radiance, float(double(pdf_a) * d2 / cos_l)};
}

// Corner weights of a bilinear warp, floored at kBilinearWeightFloor x the largest; false when none is positive.
bool floor_weights(std::array<float, 4>& w) {
  const float top = std::max(std::max(w[0], w[1]), std::max(w[2], w[3]));
  if (!(top > 0.f)) return false;
  for (float& x : w) x = std::max(x, kBilinearWeightFloor * top);
  return true;
}

// The far warp's corner weights for rectangle rc seen from p with normal n: the unoccluded contribution
// cos_p cos_light / d^2 at each corner, up to the light's distance h from p (the same for every point of the
// rectangle): (n . (q - p)) h / d^4 with h factored out. Floored; false when the rectangle lies below p's horizon
// (then n . (q - p) <= 0 over all of it, being affine in the rectangle's coordinates).
bool far_weights(const AreaLight::Rect& rc, const Vec3& p, const Vec3& n, std::array<float, 4>& w) {
  const auto g = [&](const Vec3& q) {
    const Vec3 d = q - p;
    const float d2 = glm::dot(d, d);
    return glm::dot(n, d) / (d2 * d2);
  };
  w = {g(rc.corner), g(rc.corner + rc.ex), g(rc.corner + rc.ey), g(rc.corner + rc.ex + rc.ey)};
  return floor_weights(w);
}

// The near warp's corner weights: the cosines at p towards the corners of the spherical rectangle, floored.
bool near_weights(const SphericalRectangle& sr, const Vec3& n, std::array<float, 4>& w) {
  w = sr.corner_cosines(n);
  return floor_weights(w);
}

}  // namespace

bool AreaLight::by_solid_angle(const Rect& rc, const Vec3& p, AreaSampling mode) {
  return mode == AreaSampling::kSolidAngle ||
         (mode == AreaSampling::kAuto &&
          rc.area > kAutoSolidAngleRatio * length_squared(rc.corner + 0.5f * (rc.ex + rc.ey) - p));
}

bool AreaLight::projected_near(const Rect& rc, const Vec3& p) {
  return rc.area > kAutoProjectedRatio * length_squared(rc.corner + 0.5f * (rc.ex + rc.ey) - p);
}

float AreaLight::pdf(const Vec3& p, const Vec3& q, const Vec3& nq, AreaSampling mode) const {
  return pdf(p, nullptr, q, nq, mode);
}

float AreaLight::pdf(const Vec3& p, const Vec3& n, const Vec3& q, const Vec3& nq, AreaSampling mode) const {
  return pdf(p, &n, q, nq, mode);
}

float AreaLight::pdf(const Vec3& p, const Vec3* n, const Vec3& q, const Vec3& nq, AreaSampling mode) const {
  const Vec3d w = Vec3d(p) - Vec3d(q);
  const double d2 = glm::dot(w, w);
  const double cos_l = glm::dot(Vec3d(nq), w) / std::sqrt(d2);
  if (!(cos_l > 0.0) || !(d2 > 0.0) || !(total_area > 0.f)) return 0.f;
  const float by_area = float(d2 / (cos_l * double(total_area)));  // any part picked by area, then a uniform point
  if (sphere) {
    const float r = sphere->radius;
    const float dc2 = length_squared(sphere->center - p);
    if (mode != AreaSampling::kArea && dc2 > r * r * 1.0001f) {
      const float cos_max = std::sqrt(std::max(0.f, 1.f - r * r / dc2));
      return 1.f / (2.f * kPi * (1.f - cos_max));
    }
    return by_area;
  }
  // A rectangle sampled by solid angle has density pick / (its solid angle), times the warp's density with a
  // receiver normal; every other part pick / area / cos, times the far warp's density.
  const bool warp = n && mode == AreaSampling::kAuto;
  for (const Rect& rc : rects) {
    if (!warp && !by_solid_angle(rc, p, mode)) continue;
    const Vec3 d = q - rc.corner;
    const float size = std::max(glm::length(rc.ex), glm::length(rc.ey));
    if (std::abs(glm::dot(d, rc.n)) > 1e-4f * size) continue;
    const float a = glm::dot(d, rc.ex) / glm::dot(rc.ex, rc.ex), b = glm::dot(d, rc.ey) / glm::dot(rc.ey, rc.ey);
    if (a < -1e-4f || a > 1.0001f || b < -1e-4f || b > 1.0001f) continue;
    std::array<float, 4> wt;
    if (warp && !projected_near(rc, p))
      return far_weights(rc, p, *n, wt) ? by_area * bilinear_marginals_pdf(Vec2(std::clamp(a, 0.f, 1.f), std::clamp(b, 0.f, 1.f)), wt) : 0.f;
    SphericalRectangle sr;
    if (glm::dot(rc.n, p - rc.corner) <= 0.f || !sr.init(p, rc.corner, rc.ex, rc.ey) || !(sr.solid_angle() > 0.f)) return 0.f;
    const float pick_over_s = rc.area / total_area / sr.solid_angle();
    if (!warp) return pick_over_s;
    return near_weights(sr, *n, wt) ? pick_over_s * bilinear_marginals_pdf(sr.invert(q), wt) : 0.f;
  }
  return by_area;
}

LightSample AreaLight::sample(const Vec3& p, float u_part, Vec2 u, AreaSampling mode) const {
  return sample(p, nullptr, u_part, u, mode);
}

LightSample AreaLight::sample(const Vec3& p, const Vec3& n, float u_part, Vec2 u, AreaSampling mode) const {
  return sample(p, &n, u_part, u, mode);
}

LightSample AreaLight::sample(const Vec3& p, const Vec3* n, float u_part, Vec2 u, AreaSampling mode) const {
  if (sphere) {
    const Vec3 c = sphere->center;
    const float r = sphere->radius;
    const Vec3 pc = c - p;
    const float d2 = length_squared(pc);
    if (mode != AreaSampling::kArea && d2 > r * r * 1.0001f) {
      // Uniform in the cone of directions the sphere subtends.
      const float sin2 = r * r / d2;
      const float cos_max = std::sqrt(std::max(0.f, 1.f - sin2));
      const Frame f = Frame::from_z(pc / std::sqrt(d2));
      const Vec3 w = f.to_world(sample_uniform_cone(u, cos_max));
      const auto t = intersect_sphere(*sphere, Ray{p, w}, kInfinity);
      const Vec3 q = t ? p + *t * w : c - r * f.n;
      const Vec3 nq = glm::normalize(q - c);
      const float pdf = 1.f / (2.f * kPi * (1.f - cos_max));
      const bool faces = glm::dot(nq, p - q) > 0.f;
      return {q, nq, faces ? radiance : Vec3(0.f), faces ? pdf : 0.f, gamma(7) * glm::abs(q)};
    }
    const Vec3 nq = sample_uniform_sphere(u);
    LightSample ls = from_area(p, c + r * nq, nq, 1.f / total_area, radiance);
    ls.p_error = gamma(7) * glm::abs(ls.p);
    return ls;
  }
  if (total_area <= 0.f) return {p, Vec3(0.f), Vec3(0.f), 0.f};
  float part_pdf = 1.f;
  int part = 0;
  const int nparts = part_by_area.size();
  if (nparts > 1) part_by_area.sample(u_part, &part_pdf, &part);
  const float pick = part_pdf / float(nparts);  // probability of this part
  if (part < int(rects.size())) {
    const Rect& rc = rects[size_t(part)];
    const bool warp = n && mode == AreaSampling::kAuto;  // by the unoccluded contribution (see AreaSampling::kAuto)
    if (warp ? projected_near(rc, p) : by_solid_angle(rc, p, mode)) {
      SphericalRectangle sr;
      if (glm::dot(rc.n, p - rc.corner) <= 0.f || !sr.init(p, rc.corner, rc.ex, rc.ey)) return {p, rc.n, Vec3(0.f), 0.f};
      float warp_pdf = 1.f;
      if (warp) {
        std::array<float, 4> w;
        if (!near_weights(sr, *n, w)) return {p, rc.n, Vec3(0.f), 0.f};  // the rectangle lies below p's horizon
        const WarpSample b = sample_bilinear_marginals(u, w);
        u = b.p;
        warp_pdf = b.pdf;
      }
      RectSample s = sr.sample(u);
      s.pdf *= warp_pdf;
      // Re-projected onto the rectangle in double precision so the point's error bound is one rounding.
      const Vec3d d = Vec3d(s.p) - Vec3d(rc.corner);
      const double a = std::clamp(glm::dot(d, Vec3d(rc.ex)) / glm::dot(Vec3d(rc.ex), Vec3d(rc.ex)), 0.0, 1.0);
      const double b = std::clamp(glm::dot(d, Vec3d(rc.ey)) / glm::dot(Vec3d(rc.ey), Vec3d(rc.ey)), 0.0, 1.0);
      const Vec3 q = on_plane(rc.corner, rc.ex, rc.ey, a, b);
      return {q, rc.n, radiance, s.pdf * pick, rounded_once_error(q) + gamma(2) * (glm::abs(rc.ex) + glm::abs(rc.ey))};
    }
    float warp_pdf = 1.f;
    if (warp) {
      std::array<float, 4> w;
      if (!far_weights(rc, p, *n, w)) return {p, rc.n, Vec3(0.f), 0.f};  // the rectangle lies below p's horizon
      const WarpSample b = sample_bilinear_marginals(u, w);
      u = b.p;
      warp_pdf = b.pdf;
    }
    const Vec3 q = on_plane(rc.corner, rc.ex, rc.ey, u.x, u.y);
    LightSample ls = from_area(p, q, rc.n, warp_pdf / rc.area, radiance);
    ls.pdf *= pick;
    ls.p_error = rounded_once_error(q) + gamma(2) * (glm::abs(rc.ex) + glm::abs(rc.ey));
    return ls;
  }
  const Tri& t = tris[size_t(part) - rects.size()];
  const Vec2 b = sample_uniform_triangle(u);
  const Vec3 q = on_plane(t.p0, t.p1 - t.p0, t.p2 - t.p0, b.x, b.y);
  LightSample ls = from_area(p, q, t.n, 1.f / t.area, radiance);
  ls.pdf *= pick;
  ls.p_error = rounded_once_error(q) + gamma(2) * glm::abs(t.p1 - t.p0) + gamma(2) * glm::abs(t.p2 - t.p0);
  return ls;
}

namespace {

Vec2 direction_to_uv(const Vec3& d) {
  // theta = acos(d.y) for a unit d, computed as atan2(sin, cos): acos loses half the digits near the poles.
  const float theta = portable_atan2(std::sqrt(d.x * d.x + d.z * d.z), d.y);
  float phi = portable_atan2(d.x, -d.z);
  if (phi < 0.f) phi += 2.f * kPi;
  return {phi / (2.f * kPi), theta / kPi};
}

Vec3 uv_to_direction(Vec2 uv, float* sin_theta) {
  const float theta = uv.y * kPi, phi = uv.x * 2.f * kPi;
  const SinCos t = portable_sincos(theta), p = portable_sincos(phi);
  const float st = t.sin;
  *sin_theta = st;
  // Inverse of direction_to_uv: d.x = sin(theta) sin(phi), d.z = -sin(theta) cos(phi).
  return {st * p.sin, t.cos, -st * p.cos};
}

}  // namespace

void Environment::finish() {
  if (constant() || dist) return;
  const Image& img = *texture.image;
  const int W = img.width, H = img.height;
  // Row by row in parallel: every value depends on the map alone, not on the thread that computes it.
  std::vector<float> lum(size_t(W) * size_t(H));
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) lum[size_t(y) * size_t(W) + size_t(x)] = luminance(img.at(x, y));
  });
  std::vector<float> w(lum.size());
  tbb::parallel_for(0, H, [&](int y) {
    // Largest sin(theta) over the row's band [y, y+1) / H.
    const float t0 = kPi * float(y) / float(H), t1 = kPi * float(y + 1) / float(H);
    const float st = (t0 <= kPi / 2 && t1 >= kPi / 2) ? 1.f : std::max(portable_sin(t0), portable_sin(t1));
    for (int x = 0; x < W; ++x) {
      float m = lum[size_t(y) * size_t(W) + size_t(x)];
      if (!raw_pixel_distribution) {
        // Texture::lookup wraps (repeats) in both directions, so the neighbourhood does too.
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = (x + dx + W) % W, yy = (y + dy + H) % H;
            m = std::max(m, lum[size_t(yy) * size_t(W) + size_t(xx)]);
          }
      }
      w[size_t(y) * size_t(W) + size_t(x)] = m * (raw_pixel_distribution ? portable_sin(kPi * (float(y) + 0.5f) / float(H)) : st);
    }
  });
  dist = std::make_shared<const Distribution2D>(w, W, H);
}

Vec3 Environment::radiance(const Vec3& d) const {
  if (constant()) return scale * texture.color;
  return scale * texture.lookup_latlong(direction_to_uv(to_local * d));
}

LightSample Environment::sample(Vec2 u) const {
  if (constant()) {
    const Vec3 d = sample_uniform_sphere(u);
    return {d, Vec3(0.f), scale * texture.color, 1.f / (4.f * kPi)};
  }
  float pdf_uv;
  const Vec2 uv = dist->sample(u, &pdf_uv);
  float st;
  const Vec3 local = uv_to_direction(uv, &st);
  if (!(st > 0.f) || !(pdf_uv > 0.f)) return {local, Vec3(0.f), Vec3(0.f), 0.f};
  const Vec3 d = to_world * local;
  return {d, Vec3(0.f), radiance(d), pdf_uv / (2.f * kPi * kPi * st)};
}

Vec3 Environment::radiance_and_pdf(const Vec3& d, float* pdf) const {
  if (constant()) {
    *pdf = 1.f / (4.f * kPi);
    return scale * texture.color;
  }
  const Vec3 local = to_local * d;
  const Vec2 uv = direction_to_uv(local);
  const float st = std::sqrt(local.x * local.x + local.z * local.z);
  *pdf = st > 0.f ? dist->pdf(uv) / (2.f * kPi * kPi * st) : 0.f;
  return scale * texture.lookup_latlong(uv);
}

float Environment::pdf(const Vec3& d) const {
  if (constant()) return 1.f / (4.f * kPi);
  const Vec3 local = to_local * d;
  const Vec2 uv = direction_to_uv(local);
  const float st = std::sqrt(local.x * local.x + local.z * local.z);  // sin(theta) without 1 - cos^2 cancellation
  if (!(st > 0.f)) return 0.f;
  return dist->pdf(uv) / (2.f * kPi * kPi * st);
}

}  // namespace tessera
