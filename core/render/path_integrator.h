// The unidirectional path tracer (integrator types "path" and "bdpt"): BSDF-sampled paths with Russian roulette,
// gathering light by the scene's profile: light sampling and BSDF sampling combined by the power heuristic (MIS),
// light sampling only (NEE), or BSDF sampling only (RW).
#pragma once

#include "core/render/integrator.h"

#include <array>

namespace tessera {

/// Radiance arriving along camera ray r, whose closest hit the caller traced (as for trace_radiance), estimated by
/// one path; never NaN or Inf (such samples are counted in counters.nonfinite and return zero). Paths end after
/// scene.settings.max_depth bounces at the latest.
Vec3 trace_path(const Scene& scene, Ray r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                RayCounters& counters);

/// trace_path for two camera rays and their traced closest hits, bitwise as two calls in order (the same estimates and
/// counters), with the two paths' vertices interleaved: each ray of one path is traced next to a ray of the other, so
/// the CPU overlaps two independent chains of work where one path alone would wait for each answer.
std::array<Vec3, 2> trace_path_pair(const Scene& scene, const Ray& ra, const std::optional<Hit>& ha,
                                    PixelSampler& sa, const Ray& rb, const std::optional<Hit>& hb, PixelSampler& sb,
                                    RayCounters& counters);

/// The scene's integrator for camera ray r and its traced closest hit: trace_path for IntegratorKind::kPath,
/// trace_radiance (direct lighting) otherwise.
inline Vec3 trace_sample(const Scene& scene, const Ray& r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                         RayCounters& counters) {
  return scene.settings.integrator == IntegratorKind::kPath ? trace_path(scene, r, camera_hit, sampler, counters)
                                                            : trace_radiance(scene, r, camera_hit, sampler, counters);
}

/// trace_sample for two camera rays and their traced closest hits, bitwise as two calls in order.
inline std::array<Vec3, 2> trace_sample_pair(const Scene& scene, const Ray& ra, const std::optional<Hit>& ha,
                                             PixelSampler& sa, const Ray& rb, const std::optional<Hit>& hb,
                                             PixelSampler& sb, RayCounters& counters) {
  if (scene.settings.integrator == IntegratorKind::kPath)
    return trace_path_pair(scene, ra, ha, sa, rb, hb, sb, counters);
  const Vec3 a = trace_radiance(scene, ra, ha, sa, counters);
  return {a, trace_radiance(scene, rb, hb, sb, counters)};
}

/// The scene's integrator for camera ray r, traced here.
inline Vec3 trace_sample(const Scene& scene, const Ray& r, PixelSampler& sampler, RayCounters& counters) {
  return trace_sample(scene, r, trace_closest(scene, r, RayKind::kCamera, counters), sampler, counters);
}

}  // namespace tessera
