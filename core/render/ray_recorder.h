// Observing the rays a render traces, so that a benchmark can replay them through traversal alone
// (bench/integrator_vs_traversal): each scene's "traversal-only" limit for its real mix of rays.
#pragma once

#include "core/geometry/ray.h"

#include <cstdint>

namespace tessera {

/// What a traced ray is for; the kind says which query traced it.
enum class RayKind : uint8_t {
  kCamera,    ///< A camera ray (closest hit).
  kSpecular,  ///< A continuation through a delta surface: refraction, glass, mirror (closest hit).
  kBounce,    ///< A BSDF-sampled continuation of a path (closest hit).
  kShadow,    ///< The visibility of a light sample (any hit).
};

/// Number of RayKind values.
inline constexpr int kRayKinds = 4;

/// Names of the RayKind values, in declaration order.
inline constexpr const char* kRayKindNames[kRayKinds] = {"camera", "specular", "bounce", "shadow"};

/// True when rays of this kind are traced with Bvh::occluded (any hit), false for Bvh::intersect (closest hit).
constexpr bool traced_as_any_hit(RayKind k) { return k == RayKind::kShadow; }

/// Receives every ray a render traces, from the render's threads at once: an implementation keeps what it wants
/// and must be thread-safe. Without one (the default) a render pays one predicted branch per ray and no pixel changes.
class RayRecorder {
 public:
  virtual ~RayRecorder() = default;
  /// Called once per traced ray, just before it is traced, with exactly the ray the query receives.
  virtual void record(RayKind kind, const Ray& r) = 0;
};

}  // namespace tessera
