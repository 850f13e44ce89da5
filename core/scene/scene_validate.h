// The scene loader's validate stage: checks of the whole scene once every object is in it, as warnings (errors with
// --strict): exactly coincident triangles, and features too small for float precision far from the camera.
#pragma once

#include "core/render/scene.h"
#include "core/scene/scene_json.h"

namespace tessera {

/// Warns through `json` about `scene`.
void validate_scene(const Scene& scene, SceneJson& json);

}  // namespace tessera
