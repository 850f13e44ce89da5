#include "core/render/integrator.h"

#include <algorithm>
#include <cmath>

namespace tessera {

bool refract(const Vec3& w, const Vec3& n, float eta, Vec3* wt) {
  float cos_i = glm::dot(n, w);
  Vec3 nn = n;
  float rel = 1.f / eta;  // n_outgoing_side / n_transmitted_side when w is outside (entering)
  if (cos_i < 0.f) {      // w on the inside: leaving
    rel = eta;
    cos_i = -cos_i;
    nn = -n;
  }
  // cos_t^2 = 1 - rel^2 (1 - cos_i^2), written without the cancellation of 1 - (1 - ...): for rel = 1 it is cos_i^2
  // exactly, so an index-matched surface passes rays through unbent, and grazing angles keep their precision.
  const float cos2_t = (1.f - rel * rel) + rel * rel * (cos_i * cos_i);
  if (!(cos2_t > 0.f)) return false;  // total internal reflection
  const float cos_t = std::sqrt(cos2_t);
  *wt = -rel * w + (rel * cos_i - cos_t) * nn;
  return true;
}

namespace {

// Direct lighting at a diffuse point: sp/ns oriented to the viewer's side, albedo/pi as BRDF.
Vec3 direct_lighting(const Scene& scene, const SurfaceHit& h, const Vec3& n, const Vec3& albedo, PixelSampler& sampler,
                     RayCounters& counters) {
  const Vec3 f = albedo * kInvPi;
  const IntegratorSettings& st = scene.settings;
  Vec3 L(0.f);
  if (scene.point_light) {
    const PointLight& pl = *scene.point_light;
    const Vec3 d = pl.position - h.sp.p;
    const float d2 = length_squared(d);
    const float cos_s = glm::dot(n, d) / std::sqrt(d2);
    if (cos_s > 0.f && glm::dot(h.sp.n, d) * glm::dot(h.sp.n, n) > 0.f) {
      if (!trace_occluded(scene, spawn_ray_to(h.sp, pl.position), counters)) L += f * cos_s * pl.flux / (4.f * kPi * d2);
    }
  }
  bool first = st.pair_light_with_pixel;  // the first light draw is paired with the pixel position (the last 2D draw)
  for (const AreaLight& light : scene.area_lights) {
    Vec3 sum(0.f);
    for (int k = 0; k < st.light_samples; ++k) {
      const float u_part = light.parts() > 1 ? sampler.next_1d() : 0.f;
      const Vec2 u = first ? sampler.next_2d_paired() : sampler.next_2d();
      first = false;
      const LightSample ls = light.sample(h.sp.p, n, u_part, u, st.area_sampling);
      if (!(ls.pdf > 0.f) || max_component(ls.radiance) <= 0.f) continue;
      const Vec3 wi = ls.p - h.sp.p;
      const float dist = glm::length(wi);
      const float cos_s = glm::dot(n, wi) / dist;
      if (!(cos_s > 0.f) || glm::dot(h.sp.n, wi) * glm::dot(h.sp.n, n) <= 0.f) continue;
      const SurfacePoint target{ls.p, ls.p_error, ls.n};
      if (trace_occluded(scene, spawn_ray_to(h.sp, target), counters)) continue;
      sum += f * ls.radiance * cos_s / ls.pdf;
    }
    L += sum / float(st.light_samples);
  }
  if (scene.environment) {
    const Environment& env = *scene.environment;
    const Frame frame = Frame::from_z(n);
    auto visible = [&](const Vec3& wi) {
      if (glm::dot(h.sp.n, wi) * glm::dot(h.sp.n, n) <= 0.f) return false;  // below the geometric surface
      return !trace_occluded(scene, spawn_ray(h.sp, wi), counters);
    };
    EnvSampling mode = st.env_sampling;
    if (env.constant() && (mode == EnvSampling::kMis || mode == EnvSampling::kImportance)) mode = EnvSampling::kCosine;
    // Two draws whatever the mode (the stream stays the same), each computed only when the mode uses it.
    const bool light_draw = mode != EnvSampling::kCosine;
    const bool bsdf_draw = mode == EnvSampling::kCosine || mode == EnvSampling::kMis;
    const Vec2 u_light = light_draw ? sampler.next_2d() : sampler.skip_2d();
    const Vec2 u_bsdf = bsdf_draw ? sampler.next_2d() : sampler.skip_2d();
    switch (mode) {
      case EnvSampling::kUniform: {
        const Vec3 wi = sample_uniform_sphere(u_light);
        const float c = glm::dot(n, wi);
        if (c > 0.f && visible(wi)) L += f * env.radiance(wi) * c * (4.f * kPi);
        break;
      }
      case EnvSampling::kCosine: {
        const Vec3 wi = frame.to_world(sample_cosine_hemisphere(u_bsdf));
        if (glm::dot(n, wi) > 0.f && visible(wi)) L += albedo * env.radiance(wi);  // f*cos/pdf = albedo
        break;
      }
      case EnvSampling::kImportance:
      case EnvSampling::kMis: {
        const bool mis = mode == EnvSampling::kMis;
        const LightSample ls = env.sample(u_light);
        const float c = glm::dot(n, ls.p);
        if (ls.pdf > 0.f && c > 0.f && visible(ls.p)) {
          const float w = mis ? power_heuristic(ls.pdf, c * kInvPi) : 1.f;
          L += f * ls.radiance * c * w / ls.pdf;
        }
        if (mis) {
          const Vec3 wi = frame.to_world(sample_cosine_hemisphere(u_bsdf));
          const float cb = glm::dot(n, wi);
          if (cb > 0.f && visible(wi)) {
            const float pdf_b = cb * kInvPi;
            float pdf_l;
            const Vec3 le = env.radiance_and_pdf(wi, &pdf_l);
            const float w = power_heuristic(pdf_b, pdf_l);
            L += f * le * cb * w / pdf_b;
          }
        }
        break;
      }
    }
  }
  return L;
}

}  // namespace

Vec3 trace_radiance(const Scene& scene, Ray r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                    RayCounters& counters) {
  ++counters.camera;
  Vec3 L(0.f);
  for (int depth = 0;; ++depth) {
    const auto hit = depth == 0 ? camera_hit : trace_closest(scene, r, RayKind::kSpecular, counters);
    if (!hit) {
      if (scene.environment) L += scene.environment->radiance(glm::normalize(r.d));
      break;
    }
    const SurfaceHit h = scene.surface(r, *hit);
    const Vec3 wo = -glm::normalize(r.d);
    const bool front = glm::dot(wo, h.sp.n) > 0.f;
    if (h.light >= 0 && front) L += scene.area_lights[size_t(h.light)].radiance;
    const Material& m = *h.material;
    if (m.kind == MaterialKind::kNone) break;
    if (m.kind == MaterialKind::kRefraction) {
      if (depth >= scene.settings.max_depth) break;
      Vec3 wi;
      if (!refract(wo, h.ns, m.eta, &wi)) wi = reflect(wo, glm::dot(wo, h.ns) > 0.f ? h.ns : -h.ns);
      r = spawn_ray(h.sp, wi);
      continue;
    }
    // Diffuse: one-sided surfaces reflect only on the side their normal faces.
    if (!front && !m.twosided) break;
    const Vec3 n = front ? h.ns : -h.ns;
    const Vec3 albedo = scene.textures[m.texture].evaluate(h.uv);
    L += direct_lighting(scene, h, n, albedo, sampler, counters);
    break;
  }
  if (!std::isfinite(L.x) || !std::isfinite(L.y) || !std::isfinite(L.z)) {
    ++counters.nonfinite;
    return Vec3(0.f);
  }
  return L;
}

}  // namespace tessera
