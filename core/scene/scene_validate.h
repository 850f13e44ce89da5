// The scene loader's validate stage: checks of the whole scene once every object is in it, as warnings (errors with
// --strict): exactly coincident triangles, and features too small for float precision far from the camera.
#pragma once

#include "core/render/scene.h"
#include "core/scene/scene_json.h"

#include <cstdint>
#include <vector>

namespace tessera {

/// Warns through `json` about `scene`; `triangle_object[i]` is the index in "objects" of triangle i.
void validate_scene(const Scene& scene, const std::vector<uint32_t>& triangle_object, SceneJson& json);

}  // namespace tessera
