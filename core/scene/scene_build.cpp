#include "core/scene/scene_build.h"

namespace tessera {

void build_area_light(AreaLight& light, const std::vector<Triangle>& tris, const std::vector<Vec3>& normals) {
  std::vector<bool> used(tris.size(), false);
  const bool pair_up = tris.size() <= 4096;
  for (size_t i = 0; pair_up && i < tris.size(); ++i) {
    if (used[i]) continue;
    for (size_t j = i + 1; j < tris.size() && !used[i]; ++j) {
      if (used[j] || glm::dot(normals[i], normals[j]) < 0.9999f) continue;
      const Vec3 a[3] = {tris[i].p0, tris[i].p1, tris[i].p2}, b[3] = {tris[j].p0, tris[j].p1, tris[j].p2};
      // Find the shared edge: vertex k of i not in j is the rectangle corner opposite the diagonal.
      int shared = 0, lone_i = -1, lone_j = -1;
      for (int k = 0; k < 3; ++k) {
        bool in = false;
        for (int l = 0; l < 3; ++l) in = in || a[k] == b[l];
        if (in) ++shared; else lone_i = k;
      }
      for (int l = 0; l < 3; ++l) {
        bool in = false;
        for (int k = 0; k < 3; ++k) in = in || a[k] == b[l];
        if (!in) lone_j = l;
      }
      if (shared != 2 || lone_i < 0 || lone_j < 0) continue;
      const Vec3 corner = a[lone_i];
      const Vec3 ex = a[(lone_i + 1) % 3] - corner, ey = a[(lone_i + 2) % 3] - corner;
      const Vec3 opposite = corner + ex + ey;
      const float size = std::max(glm::length(ex), glm::length(ey));
      if (glm::length(opposite - b[lone_j]) > 1e-5f * size) continue;  // not a parallelogram
      if (std::abs(glm::dot(ex, ey)) > 1e-5f * glm::length(ex) * glm::length(ey)) continue;  // not a rectangle
      light.rects.push_back({corner, ex, ey, normals[i], glm::length(glm::cross(ex, ey))});
      used[i] = used[j] = true;
    }
  }
  for (size_t i = 0; i < tris.size(); ++i)
    if (!used[i])
      light.tris.push_back({tris[i].p0, tris[i].p1, tris[i].p2, normals[i],
                            0.5f * glm::length(glm::cross(tris[i].p1 - tris[i].p0, tris[i].p2 - tris[i].p0))});
}

void build_scene(Scene& s, const BvhOptions& bvh_options) {
  for (size_t i = 0; i < s.area_lights.size(); ++i) {
    const AreaLight& l = s.area_lights[i];
    if (l.rects.empty() && l.tris.empty() && !l.sphere) {
      for (auto& a : s.triangle_attr) if (a.light == int32_t(i)) a.light = -1;
    }
  }
  s.finish(bvh_options);
}

}  // namespace tessera
