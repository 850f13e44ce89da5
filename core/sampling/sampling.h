// Sample warps and light-sampling distributions: cosine hemisphere, uniform sphere and cone, triangles,
// spherical rectangles (Urena, Fajardo, King 2013), and piecewise-constant 1D/2D distributions.
#pragma once

#include "core/util/math.h"

#include <array>
#include <span>
#include <vector>

namespace tessera {

/// An orthonormal basis around a unit vector n (Duff et al. 2017, branchless).
struct Frame {
  Vec3 s, t, n;  ///< Tangent, bitangent, normal.
  /// Builds a frame whose third axis is the unit vector n.
  static Frame from_z(const Vec3& n);
  /// World vector from local coordinates.
  Vec3 to_world(const Vec3& v) const { return v.x * s + v.y * t + v.z * n; }
  /// Local coordinates of a world vector.
  Vec3 to_local(const Vec3& v) const { return {glm::dot(v, s), glm::dot(v, t), glm::dot(v, n)}; }
};

/// Cosine-weighted direction on the hemisphere around +z (Malley's method); pdf = cos(theta)/pi.
Vec3 sample_cosine_hemisphere(Vec2 u);

/// Uniform direction on the unit sphere; pdf = 1/(4 pi).
Vec3 sample_uniform_sphere(Vec2 u);

/// Uniform direction in the cone around +z with cos(half-angle) = cos_max; pdf = 1/(2 pi (1 - cos_max)).
Vec3 sample_uniform_cone(Vec2 u, float cos_max);

/// Uniform barycentrics (b1, b2) over a triangle (b0 = 1 - b1 - b2).
Vec2 sample_uniform_triangle(Vec2 u);

/// A point of [0,1)^2 and its density.
struct WarpSample {
  Vec2 p;     ///< The point.
  float pdf;  ///< Density on the unit square.
};

/// A point x of [0,1) with density proportional to (1 - x) a + x b (a, b >= 0, not both 0), u in [0,1).
float sample_linear(float u, float a, float b);

/// Density of sample_linear at x.
float linear_pdf(float x, float a, float b);

/// Samples the product of the two marginals of the bilinear interpolation of the corner weights
/// w = {w(0,0), w(1,0), w(0,1), w(1,1)} (non-negative, not all zero): x linear from w(0,0) + w(0,1) to
/// w(1,0) + w(1,1), y linear from w(0,0) + w(1,0) to w(0,1) + w(1,1), each inverted from its own coordinate of u.
/// A separable stand-in for the bilinear density of Hart et al. (2020), whose conditional in x waits on y: equal
/// when the weights have rank one, measured as good for cosine warps over area lights, and the two square roots
/// run side by side. Stratification of u carries over to each coordinate.
WarpSample sample_bilinear_marginals(Vec2 u, const std::array<float, 4>& w);

/// Density of sample_bilinear_marginals at p.
float bilinear_marginals_pdf(Vec2 p, const std::array<float, 4>& w);

/// A point sampled on a spherical rectangle and its solid-angle density.
struct RectSample {
  Vec3 p;     ///< Point on the rectangle.
  float pdf;  ///< Density with respect to solid angle at the shading point (1 / solid angle).
};

/// A rectangle seen from a point: the spherical rectangle of Urena et al. (EGSR 2013), sampled uniformly in
/// solid angle. Only for rectangles (orthogonal edges); other parallelograms are sampled by area.
struct SphericalRectangle {
  /// Prepares sampling of rectangle (corner, corner+ex, corner+ey, corner+ex+ey) seen from o; ex and ey must
  /// be orthogonal. Returns false when o lies in the rectangle's plane (zero solid angle).
  bool init(const Vec3& o, const Vec3& corner, const Vec3& ex, const Vec3& ey);
  /// Solid angle subtended at o.
  float solid_angle() const { return S; }
  /// A uniformly distributed point (in solid angle) on the rectangle. u = (0,0), (1,0), (0,1), (1,1) map to the
  /// corners corner, corner+ex, corner+ey, corner+ex+ey, and the map is continuous in between.
  RectSample sample(Vec2 u) const;
  /// The u with which sample(u) returns the point q of the rectangle (clamped to [0,1]^2).
  Vec2 invert(const Vec3& q) const;
  /// Cosines between the unit vector n and the directions from o to the four corners, in the order of sample()'s
  /// corners: the weights of a bilinear warp that makes sample() approximately proportional to projected solid angle.
  std::array<float, 4> corner_cosines(const Vec3& n) const;

 private:
  Vec3 o_, x_, y_, z_;
  float z0, x0, y0, x1, y1, b0, b1, k, S;
  float z0sq, y0sq, y1sq;
};

/// A piecewise-constant distribution over [0,1) with n equal bins.
class Distribution1D {
 public:
  Distribution1D() = default;
  /// Builds from non-negative weights (negative or non-finite values count as 0; all-zero means uniform).
  explicit Distribution1D(std::span<const float> weights);
  /// Samples x in [0,1); returns x and sets pdf (density on [0,1)) and the bin.
  float sample(float u, float* pdf, int* bin) const;
  /// Density at x in [0,1).
  float pdf(float x) const;
  /// Number of bins.
  int size() const { return int(func_.size()); }
  /// Sum of weights divided by the bin count.
  float integral() const { return integral_; }
  /// Density in bin i (0 <= i < size()): pdf(x) for every x in that bin.
  float bin_pdf(int i) const { return func_[size_t(i)] / (integral_ > 0.f ? integral_ : 1.f); }
  /// Bytes of its tables.
  size_t bytes() const { return (func_.capacity() + cdf_.capacity()) * sizeof(float) + guide_.capacity() * sizeof(int); }

 private:
  // The first index p of cdf_ with cdf_[p] > u, as std::upper_bound over all of cdf_ finds it.
  int upper_bound_index(float u) const;

  std::vector<float> func_, cdf_;
  // guide_[b] = upper_bound_index(b / G) for the G = guide_.size() - 1 equal buckets of [0,1] (empty for few bins):
  // the search for a u in bucket b starts at guide_[b] and ends at guide_[b + 1], checked against cdf_ itself.
  std::vector<int> guide_;
  float integral_ = 0.f;
};

/// A piecewise-constant distribution over [0,1)^2 on a w x h grid (row-major, v = row).
class Distribution2D {
 public:
  Distribution2D() = default;
  /// Builds from w*h non-negative weights.
  Distribution2D(std::span<const float> weights, int w, int h);
  /// Samples (u, v) in [0,1)^2; sets pdf (density on the unit square).
  Vec2 sample(Vec2 u, float* pdf) const;
  /// Density at (u, v).
  float pdf(Vec2 uv) const;
  /// Bytes of its tables.
  size_t bytes() const;

 private:
  std::vector<Distribution1D> conditional_;
  Distribution1D marginal_;
  std::vector<float> pdf_;  // pdf() of each cell, row-major, from the same float operations as the two factors
  int w_ = 0;  // columns (the rows are conditional_.size())
};

/// Power heuristic with exponent 2 for one sample from each of two strategies.
inline float power_heuristic(float pdf_a, float pdf_b) {
  const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
  return (a + b) > 0.f ? a / (a + b) : 0.f;
}

}  // namespace tessera
