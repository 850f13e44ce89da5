// The scene loader's build stage: emitters' sampling shapes, and the finished Scene with its BVH.
#pragma once

#include "core/geometry/bvh.h"
#include "core/render/scene.h"

#include <vector>

namespace tessera {

/// Splits an emitter's triangles into rectangles (pairs forming a rectangle, sampled by solid angle) and the rest;
/// `normals` are the triangles' oriented normals.
void build_area_light(AreaLight& light, const std::vector<Triangle>& tris, const std::vector<Vec3>& normals);

/// Finishes a loaded scene: emitters that ended up without geometry (all triangles degenerate) stop emitting, then
/// the BVH, the lights' and the environment's sampling tables are built.
void build_scene(Scene& scene, const BvhOptions& bvh_options);

}  // namespace tessera
