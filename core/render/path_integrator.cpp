#include "core/render/path_integrator.h"

#include "core/render/bsdf.h"

#include <algorithm>
#include <cmath>

namespace tessera {

namespace {

// The unit normal on whose side a vertex receives light: the shading normal turned to wo's side of the surface
// (a reflecting vertex gathers light only there; the light samplers' receiver-normal strategies weight by it).
Vec3 receiver_normal(const SurfaceHit& h, const Vec3& wo) { return glm::dot(wo, h.sp.n) >= 0.f ? h.ns : -h.ns; }

// Density of the environment sample for direction d at a vertex of receiver normal nr: a constant environment is
// sampled by the cosine around nr (no direction below the receiver is drawn; a uniform sphere would waste half),
// an image by its importance.
float env_light_pdf(const Environment& env, const Vec3& d, const Vec3& nr) {
  return env.constant() ? std::max(0.f, glm::dot(d, nr)) * kInvPi : env.pdf(d);
}

// Light gathered at a non-delta vertex by sampling every light once: the point light always (a delta light, no
// other strategy can find it); area lights and the environment unless the profile is RW, weighted against BSDF
// sampling by the power heuristic under MIS. Area lights are sampled with the receiver normal nr (in proportion to
// their approximate unoccluded contribution, see AreaSampling::kAuto). The lights' 2D draws are stratified jointly
// with the sample's previous 2D draw (PixelSampler::next_2d_paired): the pixel position at the first vertex, the
// BSDF direction that led to the vertex at later ones, so that a pixel's one-bounce light (direction, point on the
// light) is a four-dimensional net rather than two independently shuffled ones.
Vec3 sample_lights(const Scene& scene, const SurfaceHit& h, const Vec3& nr, const Bsdf& bsdf, const Vec3& wo,
                   PixelSampler& sampler, RayCounters& counters) {
  const IntegratorSettings& st = scene.settings;
  const Vec3 n = h.ns;
  const bool paired = st.pair_light_with_pixel;
  auto draw_2d = [&] { return paired ? sampler.next_2d_paired() : sampler.next_2d(); };
  Vec3 L(0.f);
  auto unoccluded = [&](const Ray& ray) { return !trace_occluded(scene, ray, counters); };
  if (scene.point_light) {
    const PointLight& pl = *scene.point_light;
    const Vec3 d = pl.position - h.sp.p;
    const float d2 = length_squared(d);
    const Vec3 wi = d / std::sqrt(d2);
    const Vec3 f = bsdf.f(wo, wi);
    if (max_component(f) > 0.f && unoccluded(spawn_ray_to(h.sp, pl.position)))
      L += f * std::abs(glm::dot(n, wi)) * pl.flux / (4.f * kPi * d2);
  }
  if (st.profile == PathProfile::kRw) return L;
  const bool mis = st.profile == PathProfile::kMis;
  for (const AreaLight& light : scene.area_lights) {
    const float u_part = sampler.next_1d();
    const Vec2 u = draw_2d();
    const LightSample ls = light.sample(h.sp.p, nr, u_part, u, st.area_sampling);
    if (!(ls.pdf > 0.f) || max_component(ls.radiance) <= 0.f) continue;
    const Vec3 wi = glm::normalize(ls.p - h.sp.p);
    const Vec3 f = bsdf.f(wo, wi);
    if (max_component(f) <= 0.f) continue;
    if (!unoccluded(spawn_ray_to(h.sp, SurfacePoint{ls.p, ls.p_error, ls.n}))) continue;
    const float w = mis ? power_heuristic(ls.pdf, bsdf.pdf(wo, wi)) : 1.f;
    L += f * ls.radiance * (std::abs(glm::dot(n, wi)) * w / ls.pdf);
  }
  if (scene.environment) {
    const Environment& env = *scene.environment;
    LightSample ls;
    if (env.constant()) {
      const Vec3 wi = Frame::from_z(nr).to_world(sample_cosine_hemisphere(draw_2d()));
      ls = {wi, Vec3(0.f), env.radiance(wi), env_light_pdf(env, wi, nr)};
    } else {
      ls = env.sample(draw_2d());
    }
    const Vec3 wi = ls.p;
    if (ls.pdf > 0.f && max_component(ls.radiance) > 0.f) {
      const Vec3 f = bsdf.f(wo, wi);
      if (max_component(f) > 0.f && unoccluded(spawn_ray(h.sp, wi))) {
        const float w = mis ? power_heuristic(ls.pdf, bsdf.pdf(wo, wi)) : 1.f;
        L += f * ls.radiance * (std::abs(glm::dot(n, wi)) * w / ls.pdf);
      }
    }
  }
  return L;
}

// Weight of emission found by a BSDF-sampled ray (light_pdf: the light sampler's density for that point).
float emission_weight(PathProfile profile, bool after_delta, float bsdf_pdf, float light_pdf) {
  if (after_delta || profile == PathProfile::kRw) return 1.f;
  if (profile == PathProfile::kNee) return 0.f;
  return power_heuristic(bsdf_pdf, light_pdf);
}

}  // namespace

Vec3 trace_path(const Scene& scene, Ray r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                RayCounters& counters) {
  ++counters.camera;
  const IntegratorSettings& st = scene.settings;
  Vec3 L(0.f), beta(1.f);
  bool after_delta = true;  // the camera ray counts as a delta bounce: emitters it sees count fully
  float bsdf_pdf = 0.f;     // density of the last BSDF sample
  Vec3 prev_p(0.f);         // the vertex the current ray left
  Vec3 prev_n(0.f);         // its receiver normal
  for (int depth = 0;; ++depth) {
    const auto hit =
        depth == 0 ? camera_hit : trace_closest(scene, r, after_delta ? RayKind::kSpecular : RayKind::kBounce, counters);
    if (!hit) {
      if (scene.environment) {
        const Vec3 d = glm::normalize(r.d);
        const Environment& env = *scene.environment;
        float lp = 0.f;
        const Vec3 le = after_delta || env.constant() ? env.radiance(d) : env.radiance_and_pdf(d, &lp);
        if (!after_delta && env.constant()) lp = env_light_pdf(env, d, prev_n);
        L += beta * le * emission_weight(st.profile, after_delta, bsdf_pdf, lp);
      }
      break;
    }
    const SurfaceHit h = scene.surface(r, *hit);
    const Vec3 wo = -glm::normalize(r.d);
    if (h.light >= 0 && glm::dot(wo, h.sp.n) > 0.f) {  // emitters radiate only to the side their normal faces
      const AreaLight& light = scene.area_lights[size_t(h.light)];
      const float lp = after_delta ? 0.f : light.pdf(prev_p, prev_n, h.sp.p, h.sp.n, st.area_sampling);
      L += beta * light.radiance * emission_weight(st.profile, after_delta, bsdf_pdf, lp);
    }
    if (depth >= st.max_depth) break;
    const Material& m = *h.material;
    const Vec3 reflectance = (m.kind == MaterialKind::kDiffuse || m.kind == MaterialKind::kRoughConductor)
                                 ? scene.textures[m.texture].evaluate(h.uv)
                                 : Vec3(1.f);
    const Bsdf bsdf(m, h.ns, h.sp.n, reflectance);
    if (bsdf.black()) break;
    const Vec3 nr = receiver_normal(h, wo);
    if (!bsdf.delta()) L += beta * sample_lights(scene, h, nr, bsdf, wo, sampler, counters);
    const float uc = sampler.next_1d();
    const auto s = bsdf.sample(wo, uc, sampler.next_2d());
    if (!s) break;
    beta *= s->f * (std::abs(glm::dot(s->wi, h.ns)) / s->pdf);
    after_delta = s->delta;
    bsdf_pdf = s->pdf;
    prev_p = h.sp.p;
    prev_n = nr;
    r = spawn_ray(h.sp, s->wi);
    // Russian roulette: below the threshold a path survives with probability equal to its throughput's largest
    // channel and is reweighted by its inverse, so the estimate stays unbiased.
    const float b = max_component(beta);
    if (!std::isfinite(b) || std::isnan(beta.x + beta.y + beta.z)) {
      ++counters.nonfinite;
      return Vec3(0.f);
    }
    if (!(b > 0.f)) break;
    if (b < st.rr_threshold) {
      if (sampler.next_1d() >= b) break;
      beta /= b;
    }
  }
  if (!is_finite(L)) {
    ++counters.nonfinite;
    return Vec3(0.f);
  }
  return L;
}

}  // namespace tessera
