// The pinhole camera of the course format and its image orientation.
#pragma once

#include "core/util/math.h"
#include "core/geometry/ray.h"

namespace tessera {

/// A pinhole camera. Film coordinates (x, y) span [0,w] x [0,h] with y = 0 at the BOTTOM of the picture;
/// image pixel (px, row) has row 0 at the TOP, i.e. film y = h - row - v for v in [0,1).
struct Camera {
  Vec3 position{0.f, 0.f, 1.f};  ///< Eye point.
  Vec3 forward{0.f, 0.f, -1.f};  ///< Unit viewing direction.
  Vec3 right{1.f, 0.f, 0.f};     ///< Unit right vector: normalize(cross(forward, ref_up)).
  Vec3 up{0.f, 1.f, 0.f};        ///< Unit up vector: cross(right, forward).
  float tan_half_fov = 0.41421356f;  ///< tan(vertical fov / 2).

  /// Camera at `position` looking at `look_at`, with vertical field of view `fov_degrees`.
  static Camera look_at(const Vec3& position, const Vec3& look_at, const Vec3& ref_up, float fov_degrees);

  /// The ray through film point (fx, fy) of a w x h film (fy = 0 at the bottom), direction normalised.
  Ray generate(float fx, float fy, int w, int h) const {
    const float nx = 2.f * fx / float(w) - 1.f, ny = 2.f * fy / float(h) - 1.f;
    const float aspect = float(w) / float(h);
    const Vec3 d = nx * tan_half_fov * aspect * right + ny * tan_half_fov * up + forward;
    return Ray{position, glm::normalize(d), kInfinity};
  }

  /// The ray through image pixel (px, row) at offset (u, v) in [0,1)^2 within the pixel (row 0 = top).
  Ray generate_pixel(int px, int row, Vec2 uv, int w, int h) const {
    return generate(float(px) + uv.x, float(h - row) - uv.y, w, h);
  }
};

}  // namespace tessera
