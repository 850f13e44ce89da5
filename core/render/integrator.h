// The direct-lighting integrator ("intersection_test"): follows perfect-refraction chains, then gathers direct
// light from every light at the first diffuse surface.
#pragma once

#include "core/render/ray_recorder.h"
#include "core/sampling/sampler.h"
#include "core/render/scene.h"

#include <cstdint>
#include <optional>

namespace tessera {

/// Counters a render accumulates (per thread, summed at the end).
struct RayCounters {
  uint64_t camera = 0;     ///< Camera rays.
  uint64_t rays = 0;       ///< All rays traced (camera, specular, shadow, BSDF).
  uint64_t nonfinite = 0;  ///< Samples that came out NaN or Inf and were dropped (counted as zero).
  RayRecorder* recorder = nullptr;  ///< When set, receives every traced ray (RenderOptions::recorder).
};

/// Closest hit of r, a ray of the given kind: counted in counters.rays and shown to counters.recorder when set.
inline std::optional<Hit> trace_closest(const Scene& scene, const Ray& r, RayKind kind, RayCounters& counters) {
  ++counters.rays;
  if (counters.recorder) [[unlikely]] counters.recorder->record(kind, r);
  return scene.bvh.intersect(r);
}

/// Whether shadow ray r is blocked: counted in counters.rays and shown to counters.recorder when set.
inline bool trace_occluded(const Scene& scene, const Ray& r, RayCounters& counters) {
  ++counters.rays;
  if (counters.recorder) [[unlikely]] counters.recorder->record(RayKind::kShadow, r);
  return scene.bvh.occluded(r);
}

/// Radiance arriving along camera ray r, whose closest hit the caller traced (trace_closest, RayKind::kCamera): so
/// that the camera rays of several samples can be traced one after the other before any is shaded. Never NaN or Inf
/// (such samples are counted and return zero).
Vec3 trace_radiance(const Scene& scene, Ray r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                    RayCounters& counters);

/// Radiance arriving along camera ray r, traced here.
inline Vec3 trace_radiance(const Scene& scene, const Ray& r, PixelSampler& sampler, RayCounters& counters) {
  return trace_radiance(scene, r, trace_closest(scene, r, RayKind::kCamera, counters), sampler, counters);
}

/// Refracts w (pointing away from the surface) through normal n (unit, any orientation) for
/// eta = n_inside / n_outside, where n points to the outside. Returns false for total internal reflection.
bool refract(const Vec3& w, const Vec3& n, float eta, Vec3* wt);

/// Mirror reflection of w (pointing away from the surface) about n.
inline Vec3 reflect(const Vec3& w, const Vec3& n) { return 2.f * glm::dot(w, n) * n - w; }

}  // namespace tessera
