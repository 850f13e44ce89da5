// The unidirectional path tracer (integrator types "path" and "bdpt"): BSDF-sampled paths with Russian roulette,
// gathering light by the scene's profile: light sampling and BSDF sampling combined by the power heuristic (MIS),
// light sampling only (NEE), or BSDF sampling only (RW).
#pragma once

#include "core/integrator.h"

namespace tessera {

/// Radiance arriving along camera ray r, estimated by one path; never NaN or Inf (such samples are counted in
/// counters.nonfinite and return zero). Paths end after scene.settings.max_depth bounces at the latest.
Vec3 trace_path(const Scene& scene, Ray r, PixelSampler& sampler, RayCounters& counters);

/// The scene's integrator: trace_path for IntegratorKind::kPath, trace_radiance (direct lighting) otherwise.
inline Vec3 trace_sample(const Scene& scene, const Ray& r, PixelSampler& sampler, RayCounters& counters) {
  return scene.settings.integrator == IntegratorKind::kPath ? trace_path(scene, r, sampler, counters)
                                                            : trace_radiance(scene, r, sampler, counters);
}

}  // namespace tessera
