// The unidirectional path tracer (integrator types "path" and "bdpt"): BSDF-sampled paths with Russian roulette,
// gathering light by the scene's profile: light sampling and BSDF sampling combined by the power heuristic (MIS),
// light sampling only (NEE), or BSDF sampling only (RW).
#pragma once

#include "core/render/integrator.h"

namespace tessera {

/// Radiance arriving along camera ray r, whose closest hit the caller traced (as for trace_radiance), estimated by
/// one path; never NaN or Inf (such samples are counted in counters.nonfinite and return zero). Paths end after
/// scene.settings.max_depth bounces at the latest.
Vec3 trace_path(const Scene& scene, Ray r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                RayCounters& counters);

/// The scene's integrator for camera ray r and its traced closest hit: trace_path for IntegratorKind::kPath,
/// trace_radiance (direct lighting) otherwise.
inline Vec3 trace_sample(const Scene& scene, const Ray& r, const std::optional<Hit>& camera_hit, PixelSampler& sampler,
                         RayCounters& counters) {
  return scene.settings.integrator == IntegratorKind::kPath ? trace_path(scene, r, camera_hit, sampler, counters)
                                                            : trace_radiance(scene, r, camera_hit, sampler, counters);
}

/// The scene's integrator for camera ray r, traced here.
inline Vec3 trace_sample(const Scene& scene, const Ray& r, PixelSampler& sampler, RayCounters& counters) {
  return trace_sample(scene, r, trace_closest(scene, r, RayKind::kCamera, counters), sampler, counters);
}

}  // namespace tessera
