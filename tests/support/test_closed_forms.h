// Test-only: closed-form radiometry in double precision, and the course camera of docs/scene-format.md written out
// independently of core/render/camera.h, so image tests can compute what each pixel must show.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

namespace tessera::testing {

using Vec3d = glm::dvec3;

/// Irradiance at p (surface normal n) from a uniformly emitting polygon of radiance L seen entirely above the
/// surface: Lambert's formula E = L/2 * sum over edges of (angle the edge subtends) * (n . unit normal of the plane
/// through p and the edge), oriented so that the result is non-negative for a front-facing polygon.
inline double polygon_irradiance(const Vec3d& p, const Vec3d& n, const std::vector<Vec3d>& poly, double L) {
  double sum = 0.0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vec3d a = glm::normalize(poly[i] - p), b = glm::normalize(poly[(i + 1) % poly.size()] - p);
    const double angle = std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0));
    const Vec3d g = glm::normalize(glm::cross(a, b));
    sum += angle * glm::dot(n, g);
  }
  return 0.5 * L * std::abs(sum);
}

/// Solid angle of the axis-aligned rectangle [-a, a] x [-b, b] seen from distance d on its axis.
inline double centered_rect_solid_angle(double a, double b, double d) {
  return 4.0 * std::asin(a * b / std::sqrt((a * a + d * d) * (b * b + d * d)));
}

/// The course's pinhole camera, exactly as docs/scene-format.md states it, in double precision.
struct CourseCamera {
  Vec3d position, forward, right, up;
  double tan_half_fov;
  int w, h;

  /// The camera of a scene's `camera` block and film size.
  CourseCamera(const Vec3d& pos, const Vec3d& look_at, const Vec3d& ref_up, double fov_deg, int width, int height)
      : position(pos), w(width), h(height) {
    forward = glm::normalize(look_at - pos);
    right = glm::normalize(glm::cross(forward, ref_up));
    up = glm::cross(right, forward);
    tan_half_fov = std::tan(fov_deg * std::numbers::pi / 360.0);
  }
  /// Unnormalised direction through film point (x, y), y = 0 at the bottom.
  Vec3d direction(double x, double y) const {
    const double nx = 2.0 * x / w - 1.0, ny = 2.0 * y / h - 1.0;
    return nx * tan_half_fov * (double(w) / h) * right + ny * tan_half_fov * up + forward;
  }
  /// Film point of image pixel (px, row) at offset (u, v) in [0,1]^2; the written image's first row is the top.
  Vec3d film_of_pixel(int px, int row, double u, double v) const { return {px + u, h - (row + v), 0.0}; }
};

/// Average of f over the pixel (px, row) of `cam`'s image by the composite midpoint rule on n x n points; f takes a
/// ray (origin, unnormalised direction).
inline double pixel_average(const CourseCamera& cam, int px, int row, int n,
                            const std::function<double(const Vec3d&, const Vec3d&)>& f) {
  double sum = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Vec3d film = cam.film_of_pixel(px, row, (i + 0.5) / n, (j + 0.5) / n);
      sum += f(cam.position, cam.direction(film.x, film.y));
    }
  return sum / (double(n) * n);
}

}  // namespace tessera::testing
