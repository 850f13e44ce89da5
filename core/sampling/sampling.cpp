#include "core/sampling/sampling.h"
#include "core/util/trig.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

namespace tessera {

Frame Frame::from_z(const Vec3& n) {
  const float sign = std::copysign(1.f, n.z);
  const float a = -1.f / (sign + n.z);
  const float b = n.x * n.y * a;
  return Frame{Vec3(1.f + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3(b, sign + n.y * n.y * a, -n.y), n};
}

namespace {

// sin and cos of a in [-pi/4, pi/4] by their Taylor polynomials to degree 9 and 10 (truncation below 2e-9, under
// float rounding), in plain float operations: the same bits on every ISA, without the general range reduction.
SinCos sincos_quarter(float a) {
  const float a2 = a * a;
  const float s = a * (1.f + a2 * (-1.f / 6.f + a2 * (1.f / 120.f + a2 * (-1.f / 5040.f + a2 * (1.f / 362880.f)))));
  const float c =
      1.f + a2 * (-0.5f + a2 * (1.f / 24.f + a2 * (-1.f / 720.f + a2 * (1.f / 40320.f + a2 * (-1.f / 3628800.f)))));
  return {s, c};
}

}  // namespace

Vec3 sample_cosine_hemisphere(Vec2 u) {
  // Concentric disk mapping (Shirley-Chiu), then lift to the hemisphere. The angle is pi/4 t in the wedges around
  // the x axis and pi/2 - pi/4 t around the y axis, |t| <= 1, so one quarter-range sin/cos pair serves both.
  const Vec2 o = 2.f * u - Vec2(1.f);
  Vec2 d(0.f);
  if (o.x != 0.f || o.y != 0.f) {
    if (std::abs(o.x) > std::abs(o.y)) {
      const SinCos sc = sincos_quarter((kPi / 4.f) * (o.y / o.x));
      d = o.x * Vec2(sc.cos, sc.sin);
    } else {
      const SinCos sc = sincos_quarter((kPi / 4.f) * (o.x / o.y));
      d = o.y * Vec2(sc.sin, sc.cos);
    }
  }
  const float z = std::sqrt(std::max(0.f, 1.f - d.x * d.x - d.y * d.y));
  return {d.x, d.y, z};
}

Vec3 sample_uniform_sphere(Vec2 u) {
  const float z = 1.f - 2.f * u.x;
  const float r = std::sqrt(std::max(0.f, 1.f - z * z));
  const SinCos sc = portable_sincos(2.f * kPi * u.y);
  return {r * sc.cos, r * sc.sin, z};
}

Vec3 sample_uniform_cone(Vec2 u, float cos_max) {
  const float cos_t = (1.f - u.x) + u.x * cos_max;
  const float sin_t = std::sqrt(std::max(0.f, 1.f - cos_t * cos_t));
  const SinCos sc = portable_sincos(2.f * kPi * u.y);
  return {sin_t * sc.cos, sin_t * sc.sin, cos_t};
}

Vec2 sample_uniform_triangle(Vec2 u) {
  // Area-preserving square-to-triangle map without a fold (Heitz 2019's low-distortion variant).
  float b0, b1;
  if (u.x < u.y) {
    b0 = u.x / 2.f;
    b1 = u.y - b0;
  } else {
    b1 = u.y / 2.f;
    b0 = u.x - b1;
  }
  return {b1, 1.f - b0 - b1};
}

float sample_linear(float u, float a, float b) {
  // Inverts the CDF (a x + (b - a) x^2 / 2) / ((a + b) / 2) = u, with the root written without cancellation.
  if (u == 0.f && a == 0.f) return 0.f;
  const float x = u * (a + b) / (a + std::sqrt((1.f - u) * a * a + u * b * b));
  return std::min(x, 0x1.fffffep-1f);
}

float linear_pdf(float x, float a, float b) {
  const float sum = a + b;
  return sum > 0.f ? 2.f * ((1.f - x) * a + x * b) / sum : 0.f;
}

WarpSample sample_bilinear_marginals(Vec2 u, const std::array<float, 4>& w) {
  const Vec2 p(sample_linear(u.x, w[0] + w[2], w[1] + w[3]), sample_linear(u.y, w[0] + w[1], w[2] + w[3]));
  return {p, bilinear_marginals_pdf(p, w)};
}

float bilinear_marginals_pdf(Vec2 p, const std::array<float, 4>& w) {
  return linear_pdf(p.x, w[0] + w[2], w[1] + w[3]) * linear_pdf(p.y, w[0] + w[1], w[2] + w[3]);
}

std::array<float, 4> SphericalRectangle::corner_cosines(const Vec3& n) const {
  const Vec3 nl(glm::dot(n, x_), glm::dot(n, y_), glm::dot(n, z_));
  const auto c = [&](float x, float y, float ysq) {
    return (nl.x * x + nl.y * y + nl.z * z0) / std::sqrt(x * x + ysq + z0sq);
  };
  return {c(x0, y0, y0sq), c(x1, y0, y0sq), c(x0, y1, y1sq), c(x1, y1, y1sq)};
}

bool SphericalRectangle::init(const Vec3& o, const Vec3& corner, const Vec3& ex, const Vec3& ey) {
  o_ = o;
  const float exl = glm::length(ex), eyl = glm::length(ey);
  x_ = ex / exl;
  y_ = ey / eyl;
  z_ = glm::cross(x_, y_);
  const Vec3 d = corner - o;
  z0 = glm::dot(d, z_);
  if (z0 > 0.f) {  // orient z away from the rectangle
    z_ = -z_;
    z0 = -z0;
  }
  if (!(z0 < 0.f)) return false;
  x0 = glm::dot(d, x_);
  y0 = glm::dot(d, y_);
  x1 = x0 + exl;
  y1 = y0 + eyl;
  z0sq = z0 * z0;
  y0sq = y0 * y0;
  y1sq = y1 * y1;
  // Normals of the four planes through o and the rectangle's edges.
  const Vec3 v00(x0, y0, z0), v01(x0, y1, z0), v10(x1, y0, z0), v11(x1, y1, z0);
  const Vec3 n0 = glm::normalize(glm::cross(v00, v10));
  const Vec3 n1 = glm::normalize(glm::cross(v10, v11));
  const Vec3 n2 = glm::normalize(glm::cross(v11, v01));
  const Vec3 n3 = glm::normalize(glm::cross(v01, v00));
  // Internal angles of the spherical rectangle.
  const float g0 = portable_acos(std::clamp(-glm::dot(n0, n1), -1.f, 1.f));
  const float g1 = portable_acos(std::clamp(-glm::dot(n1, n2), -1.f, 1.f));
  const float g2 = portable_acos(std::clamp(-glm::dot(n2, n3), -1.f, 1.f));
  const float g3 = portable_acos(std::clamp(-glm::dot(n3, n0), -1.f, 1.f));
  b0 = n0.z;
  b1 = n2.z;
  k = 2.f * kPi - g2 - g3;
  S = g0 + g1 - k;
  return S > 0.f && std::isfinite(S);
}

RectSample SphericalRectangle::sample(Vec2 u) const {
  // Invert the solid angle along x: pick the spherical-rectangle slice au, then the height within it.
  const float au = u.x * S + k;
  const SinCos sc = portable_sincos(au);
  const float fu = (sc.cos * b0 - b1) / sc.sin;
  float cu = std::copysign(1.f, fu) / std::sqrt(fu * fu + b0 * b0);
  cu = std::clamp(cu, -1.f, 1.f);
  float xu = -(cu * z0) / std::sqrt(std::max(0.f, 1.f - cu * cu));
  xu = std::clamp(xu, x0, x1);
  const float dd = std::sqrt(xu * xu + z0sq);
  const float h0 = y0 / std::sqrt(dd * dd + y0sq);
  const float h1 = y1 / std::sqrt(dd * dd + y1sq);
  const float hv = h0 + u.y * (h1 - h0), hv2 = hv * hv;
  const float yv = (hv2 < 1.f - 1e-6f) ? (hv * dd) / std::sqrt(1.f - hv2) : y1;
  const Vec3 p = o_ + xu * x_ + std::clamp(yv, y0, y1) * y_ + z0 * z_;
  return {p, 1.f / S};
}

Vec2 SphericalRectangle::invert(const Vec3& q) const {
  const Vec3 d = q - o_;
  const float xq = std::clamp(glm::dot(d, x_), x0, x1), yq = std::clamp(glm::dot(d, y_), y0, y1);
  // u.x: the solid angle of the part of the rectangle left of xq, over the whole's.
  float ux = 0.f;
  SphericalRectangle left;
  if (xq > x0 && left.init(o_, o_ + x0 * x_ + y0 * y_ + z0 * z_, (xq - x0) * x_, (y1 - y0) * y_))
    ux = std::min(1.f, left.solid_angle() / S);
  // u.y: where yq lies between the heights h0 and h1 of sample()'s slice through xq.
  const float dd2 = xq * xq + z0sq;
  const float h0 = y0 / std::sqrt(dd2 + y0sq), h1 = y1 / std::sqrt(dd2 + y1sq), hq = yq / std::sqrt(dd2 + yq * yq);
  const float uy = h1 > h0 ? std::clamp((hq - h0) / (h1 - h0), 0.f, 1.f) : 0.f;
  return {ux, uy};
}

Distribution1D::Distribution1D(std::span<const float> weights) {
  const size_t n = std::max<size_t>(1, weights.size());
  func_.assign(n, 0.f);
  for (size_t i = 0; i < weights.size(); ++i) func_[i] = (weights[i] > 0.f && std::isfinite(weights[i])) ? weights[i] : 0.f;
  cdf_.assign(n + 1, 0.f);
  double acc = 0.0;
  for (size_t i = 0; i < n; ++i) {
    acc += double(func_[i]) / double(n);
    cdf_[i + 1] = float(acc);
  }
  integral_ = float(acc);
  if (!(acc > 0.0)) {
    std::fill(func_.begin(), func_.end(), 1.f);
    for (size_t i = 0; i <= n; ++i) cdf_[i] = float(i) / float(n);
    integral_ = 0.f;
    return;
  }
  for (size_t i = 1; i <= n; ++i) cdf_[i] = float(double(cdf_[i]) / acc);
  cdf_[n] = 1.f;
  // A guide for large tables (an environment map's rows and columns): binary search over a few entries instead of
  // all of them. Small ones (an emitter's parts) are searched whole.
  // The thresholds b / n grow with b, so one pass over the cdf finds every bucket's upper bound.
  if (n >= 16) {
    guide_.resize(n + 1);
    size_t p = 0;
    for (size_t b = 0; b <= n; ++b) {
      const float threshold = float(b) / float(n);
      while (p < cdf_.size() && !(threshold < cdf_[p])) ++p;
      guide_[b] = int(p);
    }
  }
}

int Distribution1D::upper_bound_index(float u) const {
  const int end = int(cdf_.size());
  int a = 0, c = end;
  if (!guide_.empty() && u >= 0.f && u < 1.f) {
    const int g = int(guide_.size()) - 1;
    const int b = std::min(int(u * float(g)), g - 1);
    a = guide_[size_t(b)];
    c = guide_[size_t(b) + 1];
    // The bucket's bounds hold if cdf_[a - 1] <= u < cdf_[c]; where rounding of u * g broke one, search past it.
    if (a > 0 && cdf_[size_t(a) - 1] > u) a = 0;
    if (c < end && !(cdf_[size_t(c)] > u)) c = end;
  }
  // Every entry before a is <= u and cdf_[c] > u (or c is the end), so the first entry > u in [a, c) (or c) is
  // the first in all of cdf_.
  return int(std::upper_bound(cdf_.begin() + a, cdf_.begin() + c, u) - cdf_.begin());
}

float Distribution1D::sample(float u, float* pdf, int* bin) const {
  const int n = int(func_.size());
  // Last index i with cdf[i] <= u.
  int i = std::clamp(upper_bound_index(u) - 1, 0, n - 1);
  while (i < n - 1 && func_[i] == 0.f) ++i;  // never land in an empty bin through rounding
  const float width = cdf_[i + 1] - cdf_[i];
  float du = width > 0.f ? (u - cdf_[i]) / width : 0.5f;
  du = std::clamp(du, 0.f, 0x1.fffffep-1f);
  if (pdf) *pdf = bin_pdf(i);
  if (bin) *bin = i;
  return std::min((float(i) + du) / float(n), 0x1.fffffep-1f);
}

float Distribution1D::pdf(float x) const {
  const int n = int(func_.size());
  return bin_pdf(std::clamp(int(x * float(n)), 0, n - 1));
}

Distribution2D::Distribution2D(std::span<const float> weights, int w, int h) {
  // Rows are independent, so they are built in parallel; each row's arithmetic is the same on any thread count.
  conditional_.resize(size_t(std::max(0, h)));
  std::vector<float> row_integrals(static_cast<size_t>(std::max(0, h)));
  tbb::parallel_for(0, std::max(0, h), [&](int y) {
    conditional_[size_t(y)] = Distribution1D(weights.subspan(size_t(y) * size_t(w), size_t(w)));
    row_integrals[size_t(y)] = conditional_[size_t(y)].integral();
  });
  marginal_ = Distribution1D(row_integrals);
  w_ = std::max(1, w);
  pdf_.resize(size_t(w_) * size_t(std::max(0, h)));
  tbb::parallel_for(0, std::max(0, h), [&](int y) {
    for (int x = 0; x < w_; ++x)
      pdf_[size_t(y) * size_t(w_) + size_t(x)] = marginal_.bin_pdf(y) * conditional_[size_t(y)].bin_pdf(x);
  });
}

size_t Distribution2D::bytes() const {
  size_t n = marginal_.bytes() + pdf_.capacity() * sizeof(float) + conditional_.capacity() * sizeof(Distribution1D);
  for (const Distribution1D& d : conditional_) n += d.bytes();
  return n;
}

Vec2 Distribution2D::sample(Vec2 u, float* pdf) const {
  float pdf_v, pdf_u;
  int row;
  const float v = marginal_.sample(u.y, &pdf_v, &row);
  const float x = conditional_[size_t(row)].sample(u.x, &pdf_u, nullptr);
  *pdf = pdf_u * pdf_v;
  return {x, v};
}

float Distribution2D::pdf(Vec2 uv) const {
  // marginal_.pdf(uv.y) * conditional_[row].pdf(uv.x), looked up.
  if (pdf_.empty()) return 0.f;
  const int h = int(conditional_.size());
  const int row = std::clamp(int(uv.y * float(h)), 0, h - 1);
  const int col = std::clamp(int(uv.x * float(w_)), 0, w_ - 1);
  return pdf_[size_t(row) * size_t(w_) + size_t(col)];
}

}  // namespace tessera
