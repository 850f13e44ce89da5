// The surface a camera ray describes in the output layers: the first one it reaches that is not purely specular.
#pragma once

#include "core/render/scene.h"

#include <cstdint>

namespace tessera {

/// What the first-hit layers record of one camera sample.
struct FirstHit {
  bool hit = false;        ///< A non-specular surface was reached (else the ray left the scene or the chain ended).
  Vec3 p{0.f};             ///< The point, in the scene's camera-centred coordinates.
  Vec3 n{0.f};             ///< Its shading normal, turned towards the ray that reached it.
  Vec3 albedo{0.f};        ///< Its reflectance (see Layer::kAlbedo).
  uint32_t material = 0;   ///< Index into scene.materials (0: no material).
  uint32_t object = 0;     ///< 1 + index into scene.object_names (0: none known).
};

/// Follows camera ray r through `refraction` and `glass` surfaces (refracted, or mirrored under total internal
/// reflection; at most scene.settings.max_depth of them) to the first other surface. Deterministic: it draws no
/// random number and touches no counter, so the beauty image never depends on it.
FirstHit first_hit(const Scene& scene, Ray r);

}  // namespace tessera
