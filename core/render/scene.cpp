#include "core/render/scene.h"
#include "core/util/trig.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace tessera {

void Scene::finish(const BvhOptions& bvh_options) {
  bvh = Bvh::build(triangles, spheres, bvh_options);
  triangle_surfaces.resize(triangles.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, triangles.size(), 16384), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) triangle_surfaces[i] = triangle_surface(triangles[i]);
  });
  for (auto& l : area_lights) l.finish();
  if (environment) environment->finish();
}

SurfaceHit Scene::surface(const Ray& r, const Hit& h) const {
  SurfaceHit s;
  const uint32_t ntri = bvh.triangle_count();
  if (h.prim < ntri) {
    const float b0 = 1.f - h.b1 - h.b2;
    s.sp = triangle_surface_point(triangles[h.prim], triangle_surfaces[h.prim], b0, h.b1, h.b2);
    const PrimAttr& a = triangle_attr[h.prim];
    if (a.flip) s.sp.n = -s.sp.n;
    s.ns = s.sp.n;
    s.uv = Vec2(0.f);
    if (a.shading >= 0) {
      const TriangleShading& sh = triangle_shading[size_t(a.shading)];
      s.uv = b0 * sh.uv[0] + h.b1 * sh.uv[1] + h.b2 * sh.uv[2];
      if (sh.has_normals) {
        const Vec3 n = b0 * sh.n[0] + h.b1 * sh.n[1] + h.b2 * sh.n[2];
        if (length_squared(n) > 0.f) {
          s.ns = glm::normalize(n);
          if (glm::dot(s.ns, s.sp.n) < 0.f) s.ns = -s.ns;  // shading normals never contradict orientation
        }
      }
    }
    s.material = &materials[a.material];
    s.light = a.light;
  } else {
    const uint32_t i = h.prim - ntri;
    const Sphere& sph = spheres[i];
    s.sp = sphere_surface_point(sph, r, h.t);
    s.ns = s.sp.n;
    // Spherical uv: u around +y, v from the top pole, as for the environment map.
    const Vec3 d = s.sp.n;
    float phi = portable_atan2(d.x, -d.z);
    if (phi < 0.f) phi += 2.f * kPi;
    s.uv = Vec2(phi / (2.f * kPi), portable_acos(std::clamp(d.y, -1.f, 1.f)) / kPi);
    s.material = &materials[sphere_attr[i].material];
    s.light = sphere_attr[i].light;
  }
  return s;
}

}  // namespace tessera
