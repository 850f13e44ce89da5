#include "core/render/camera.h"
#include "core/util/trig.h"

#include <stdexcept>

namespace tessera {

Camera Camera::look_at(const Vec3& position, const Vec3& target, const Vec3& ref_up, float fov_degrees) {
  Camera c;
  c.position = position;
  const Vec3 f = target - position;
  if (!(length_squared(f) > 0.f)) throw std::invalid_argument("camera.look_at equals camera.position");
  c.forward = glm::normalize(f);
  const Vec3 r = glm::cross(c.forward, ref_up);
  if (!(length_squared(r) > 0.f)) throw std::invalid_argument("camera.ref_up is parallel to the viewing direction");
  c.right = glm::normalize(r);
  c.up = glm::cross(c.right, c.forward);
  if (!(fov_degrees > 0.f && fov_degrees < 180.f)) throw std::invalid_argument("camera.fov must lie in (0, 180) degrees");
  c.tan_half_fov = portable_tan(fov_degrees * kPi / 360.f);
  return c;
}

}  // namespace tessera
