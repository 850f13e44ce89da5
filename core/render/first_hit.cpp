#include "core/render/first_hit.h"

#include "core/geometry/spawn.h"
#include "core/render/fresnel.h"
#include "core/render/integrator.h"

namespace tessera {

namespace {

uint32_t object_of(const Scene& scene, uint32_t prim) {
  const uint32_t ntri = scene.bvh.triangle_count();
  if (prim < ntri) return prim < scene.triangle_object.size() ? scene.triangle_object[prim] + 1 : 0;
  const uint32_t s = prim - ntri;
  return s < scene.sphere_object.size() ? scene.sphere_object[s] + 1 : 0;
}

}  // namespace

FirstHit first_hit(const Scene& scene, Ray r) {
  FirstHit out;
  for (int depth = 0;; ++depth) {
    const std::optional<Hit> hit = scene.bvh.intersect(r);
    if (!hit) return out;
    const SurfaceHit h = scene.surface(r, *hit);
    const Vec3 wo = -glm::normalize(r.d);
    const Material& m = *h.material;
    if (m.kind == MaterialKind::kRefraction || m.kind == MaterialKind::kGlass) {
      if (depth >= scene.settings.max_depth) return out;
      Vec3 wi;
      if (!refract(wo, h.ns, m.eta, &wi)) wi = reflect(wo, glm::dot(wo, h.ns) > 0.f ? h.ns : -h.ns);
      r = spawn_ray(h.sp, wi);
      continue;
    }
    out.hit = true;
    out.p = h.sp.p;
    out.n = glm::dot(wo, h.ns) >= 0.f ? h.ns : -h.ns;
    out.material = uint32_t(h.material - scene.materials.data());
    out.object = object_of(scene, hit->prim);
    if (m.kind == MaterialKind::kDiffuse) {
      out.albedo = scene.textures[m.texture].evaluate(h.uv);
    } else if (m.kind == MaterialKind::kRoughConductor) {
      out.albedo = fresnel_conductor(1.f, m.eta_t / m.eta_i, m.k / m.eta_i) * scene.textures[m.texture].evaluate(h.uv);
    }
    return out;
  }
}

}  // namespace tessera
