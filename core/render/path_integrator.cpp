#include "core/render/path_integrator.h"

#include "core/render/bsdf.h"

#include <algorithm>
#include <array>
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

// A vertex's light samples waiting for their shadow rays: each candidate's contribution with the ray that decides it.
// gather() traces them in the order they came and adds the unoccluded ones to a running sum, the additions that
// tracing each at once would make, so the sum is bitwise the same; in between the vertex samples its BSDF, work the
// CPU then overlaps with the shadow rays' traversal instead of waiting for their answers first.
class ShadowQueue {
 public:
  // Queues contribution c, counted when ray is unoccluded.
  void push(const Scene& scene, const Ray& ray, const Vec3& c, RayCounters& counters) {
    if (n_ == kCapacity) flush(scene, counters);
    items_[n_++] = {ray, c};
  }
  // The sum of the unoccluded contributions, in the order they were queued.
  Vec3 gather(const Scene& scene, RayCounters& counters) {
    flush(scene, counters);
    return sum_;
  }

 private:
  static constexpr int kCapacity = 4;
  void flush(const Scene& scene, RayCounters& counters) {
    for (int i = 0; i < n_; ++i)
      if (!trace_occluded(scene, items_[i].ray, counters)) sum_ += items_[i].c;
    n_ = 0;
  }
  struct Item {
    Ray ray;
    Vec3 c;
  };
  Item items_[kCapacity];
  int n_ = 0;
  Vec3 sum_{0.f};
};

// Light gathered at a non-delta vertex by sampling every light once, queued in `shadows` to be traced: the point
// light always (a delta light, no other strategy can find it); area lights and the environment unless the profile is
// RW, weighted against BSDF sampling by the power heuristic under MIS. Area lights are sampled with the receiver
// normal nr (in proportion to their approximate unoccluded contribution, see AreaSampling::kAuto). The lights' 2D
// draws are stratified jointly with the sample's previous 2D draw (PixelSampler::next_2d_paired): the pixel position
// at the first vertex, the BSDF direction that led to the vertex at later ones, so that a pixel's one-bounce light
// (direction, point on the light) is a four-dimensional net rather than two independently shuffled ones.
void sample_lights(const Scene& scene, const SurfaceHit& h, const Vec3& nr, const Bsdf& bsdf, const Vec3& wo,
                   PixelSampler& sampler, ShadowQueue& shadows, RayCounters& counters) {
  const IntegratorSettings& st = scene.settings;
  const Vec3 n = h.ns;
  const bool paired = st.pair_light_with_pixel;
  auto draw_2d = [&] { return paired ? sampler.next_2d_paired() : sampler.next_2d(); };
  if (scene.point_light) {
    const PointLight& pl = *scene.point_light;
    const Vec3 d = pl.position - h.sp.p;
    const float d2 = length_squared(d);
    const Vec3 wi = d / std::sqrt(d2);
    const Vec3 f = bsdf.f(wo, wi);
    if (max_component(f) > 0.f)
      shadows.push(scene, spawn_ray_to(h.sp, pl.position), f * std::abs(glm::dot(n, wi)) * pl.flux / (4.f * kPi * d2),
                   counters);
  }
  if (st.profile == PathProfile::kRw) return;
  const bool mis = st.profile == PathProfile::kMis;
  for (const AreaLight& light : scene.area_lights) {
    // A light of one part does not use its part choice (whose dimension is still taken).
    const float u_part = light.parts() > 1 ? sampler.next_1d() : sampler.skip_1d();
    const Vec2 u = draw_2d();
    const LightSample ls = light.sample(h.sp.p, nr, u_part, u, st.area_sampling);
    if (!(ls.pdf > 0.f) || max_component(ls.radiance) <= 0.f) continue;
    const Vec3 wi = glm::normalize(ls.p - h.sp.p);
    float bsdf_pdf;
    const Vec3 f = bsdf.f(wo, wi, &bsdf_pdf);
    if (max_component(f) <= 0.f) continue;
    const float w = mis ? power_heuristic(ls.pdf, bsdf_pdf) : 1.f;
    shadows.push(scene, spawn_ray_to(h.sp, SurfacePoint{ls.p, ls.p_error, ls.n}),
                 f * ls.radiance * (std::abs(glm::dot(n, wi)) * w / ls.pdf), counters);
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
      float bsdf_pdf;
      const Vec3 f = bsdf.f(wo, wi, &bsdf_pdf);
      if (max_component(f) > 0.f) {
        const float w = mis ? power_heuristic(ls.pdf, bsdf_pdf) : 1.f;
        shadows.push(scene, spawn_ray(h.sp, wi), f * ls.radiance * (std::abs(glm::dot(n, wi)) * w / ls.pdf), counters);
      }
    }
  }
}

// Weight of emission found by a BSDF-sampled ray (light_pdf: the light sampler's density for that point).
float emission_weight(PathProfile profile, bool after_delta, float bsdf_pdf, float light_pdf) {
  if (after_delta || profile == PathProfile::kRw) return 1.f;
  if (profile == PathProfile::kNee) return 0.f;
  return power_heuristic(bsdf_pdf, light_pdf);
}

// A path's state between vertices: the ray to trace next and what the vertices so far have gathered.
struct PathState {
  Ray r;                    // the ray whose closest hit is the next vertex
  Vec3 L{0.f}, beta{1.f};  // radiance gathered, throughput
  bool after_delta = true;  // the camera ray counts as a delta bounce: emitters it sees count fully
  float bsdf_pdf = 0.f;     // density of the last BSDF sample
  Vec3 prev_p{0.f};         // the vertex the current ray left
  Vec3 prev_n{0.f};         // its receiver normal
  int depth = 0;            // bounces so far
};

// The kind of s.r: a continuation after a delta bounce or a BSDF-sampled one.
RayKind next_kind(const PathState& s) { return s.after_delta ? RayKind::kSpecular : RayKind::kBounce; }

// The vertex at `hit`, the closest hit of s.r: gathers its emission and light, samples the BSDF and plays Russian
// roulette. True when the path goes on along the new s.r; false when it ended (a throughput that is not finite is
// counted in counters.nonfinite and leaves s.L zero).
bool path_vertex(const Scene& scene, PathState& s, const std::optional<Hit>& hit, PixelSampler& sampler,
                 RayCounters& counters) {
  const IntegratorSettings& st = scene.settings;
  if (!hit) {
    if (scene.environment) {
      const Vec3 d = glm::normalize(s.r.d);
      const Environment& env = *scene.environment;
      float lp = 0.f;
      const Vec3 le = s.after_delta || env.constant() ? env.radiance(d) : env.radiance_and_pdf(d, &lp);
      if (!s.after_delta && env.constant()) lp = env_light_pdf(env, d, s.prev_n);
      s.L += s.beta * le * emission_weight(st.profile, s.after_delta, s.bsdf_pdf, lp);
    }
    return false;
  }
  const SurfaceHit h = scene.surface(s.r, *hit);
  const Vec3 wo = -glm::normalize(s.r.d);
  if (h.light >= 0 && glm::dot(wo, h.sp.n) > 0.f) {  // emitters radiate only to the side their normal faces
    const AreaLight& light = scene.area_lights[size_t(h.light)];
    const float lp = s.after_delta ? 0.f : light.pdf(s.prev_p, s.prev_n, h.sp.p, h.sp.n, st.area_sampling);
    s.L += s.beta * light.radiance * emission_weight(st.profile, s.after_delta, s.bsdf_pdf, lp);
  }
  if (s.depth >= st.max_depth) return false;
  const Material& m = *h.material;
  const Vec3 reflectance = (m.kind == MaterialKind::kDiffuse || m.kind == MaterialKind::kRoughConductor)
                               ? scene.textures[m.texture].evaluate(h.uv)
                               : Vec3(1.f);
  const Bsdf bsdf(m, h.ns, h.sp.n, reflectance);
  if (bsdf.black()) return false;
  const Vec3 nr = receiver_normal(h, wo);
  ShadowQueue shadows;
  if (!bsdf.delta()) sample_lights(scene, h, nr, bsdf, wo, sampler, shadows, counters);
  const float uc = bsdf.lobe_choice() ? sampler.next_1d() : sampler.skip_1d();
  const auto bs = bsdf.sample(wo, uc, sampler.next_2d());
  // The light samples' shadow rays are traced only now, the BSDF sample taken (see ShadowQueue).
  if (!bsdf.delta()) s.L += s.beta * shadows.gather(scene, counters);
  if (!bs) return false;
  s.beta *= bs->f * (std::abs(glm::dot(bs->wi, h.ns)) / bs->pdf);
  s.after_delta = bs->delta;
  s.bsdf_pdf = bs->pdf;
  s.prev_p = h.sp.p;
  s.prev_n = nr;
  s.r = spawn_ray(h.sp, bs->wi);
  ++s.depth;
  // Russian roulette: below the threshold a path survives with probability equal to its throughput's largest
  // channel and is reweighted by its inverse, so the estimate stays unbiased.
  const float b = max_component(s.beta);
  if (!std::isfinite(b) || std::isnan(s.beta.x + s.beta.y + s.beta.z)) {
    ++counters.nonfinite;
    s.L = Vec3(0.f);
    return false;
  }
  if (!(b > 0.f)) return false;
  if (b < st.rr_threshold) {
    if (sampler.next_1d() >= b) return false;
    s.beta /= b;
  }
  return true;
}

// The estimate of an ended path: its radiance, or zero (counted) when that is not finite.
Vec3 path_result(const PathState& s, RayCounters& counters) {
  if (!is_finite(s.L)) {
    ++counters.nonfinite;
    return Vec3(0.f);
  }
  return s.L;
}

}  // namespace

Vec3 trace_path(const Scene& scene, Ray r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                RayCounters& counters) {
  ++counters.camera;
  PathState s{r};
  bool going = path_vertex(scene, s, camera_hit, sampler, counters);
  while (going) going = path_vertex(scene, s, trace_closest(scene, s.r, next_kind(s), counters), sampler, counters);
  return path_result(s, counters);
}

std::array<Vec3, 2> trace_path_pair(const Scene& scene, const Ray& ra, const std::optional<Hit>& ha,
                                    PixelSampler& sa, const Ray& rb, const std::optional<Hit>& hb, PixelSampler& sb,
                                    RayCounters& counters) {
  counters.camera += 2;
  PathState a{ra}, b{rb};
  bool going_a = path_vertex(scene, a, ha, sa, counters);
  bool going_b = path_vertex(scene, b, hb, sb, counters);
  // Both rays are traced before either vertex is shaded: the two paths' work is independent, so the CPU overlaps it.
  while (going_a && going_b) {
    const std::optional<Hit> hit_a = trace_closest(scene, a.r, next_kind(a), counters);
    const std::optional<Hit> hit_b = trace_closest(scene, b.r, next_kind(b), counters);
    going_a = path_vertex(scene, a, hit_a, sa, counters);
    going_b = path_vertex(scene, b, hit_b, sb, counters);
  }
  while (going_a) going_a = path_vertex(scene, a, trace_closest(scene, a.r, next_kind(a), counters), sa, counters);
  while (going_b) going_b = path_vertex(scene, b, trace_closest(scene, b.r, next_kind(b), counters), sb, counters);
  return {path_result(a, counters), path_result(b, counters)};
}

}  // namespace tessera
