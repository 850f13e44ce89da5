// Camera-relative coordinates: the loader re-expresses every scene position, in double precision, in a frame centred
// on the camera, so that rays near the camera work at full float precision wherever the scene lies in its file.
#pragma once

#include "core/util/math.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace tessera {

struct Scene;

/// The frame: the scene file's coordinates minus `origin`, computed in double and rounded once to float.
struct CameraFrame {
  glm::dvec3 origin{0.0};  ///< The camera position in the scene file's coordinates.

  /// A point of the scene file in the frame.
  Vec3 local(const glm::dvec3& p) const { return Vec3(p - origin); }
};

/// The frame of scene JSON j: centred on camera.position as written, or on the loader's default camera position
/// (0, 0, 1) when it is absent or malformed (the camera's own parse reports a malformed one). A function of the
/// scene alone, so every tile, worker and machine renders in the same frame.
CameraFrame camera_frame(const nlohmann::json& j);

/// Shortest edge (triangles) or radius (spheres), in float spacings at the primitive's distance from the camera, below
/// which the loader warns: rounding then moves a vertex by more than 1/128 of the feature's size.
inline constexpr double kMinFeatureSpacings = 64.0;

/// Warnings (prefixed with `name`) for geometry whose features are below kMinFeatureSpacings float spacings at their
/// distance from the camera: far from the camera a float cannot keep them apart (the spacing is 1 unit from 8.4e6
/// to 1.7e7 units).
std::vector<std::string> precision_warnings(const Scene& s, const std::string& name);

}  // namespace tessera
