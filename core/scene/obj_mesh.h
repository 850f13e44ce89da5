// Wavefront OBJ meshes for the scene loader (its resolve-assets stage): a file's triangles, transformed into the
// camera-relative frame, with per-triangle shading data; zero-area triangles are skipped with a warning.
#pragma once

#include "core/render/camera_frame.h"
#include "core/scene/scene_json.h"
#include "core/geometry/triangle.h"

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace tessera {

/// An OBJ file's triangles, ready for the scene.
struct ObjMesh {
  std::vector<Triangle> tris;
  std::vector<TriangleShading> shading;  ///< One per triangle when the OBJ has normals or uvs.
  std::vector<bool> flip;                ///< The shading normals point against the winding's normal.
  bool has_shading = false;
};

/// An OBJ file as parsed, before any transform (defined in obj_mesh.cpp).
struct ParsedObj;

/// OBJ files parsed by earlier loads, by path, for files that do not change while it lives (a content-addressed
/// store's): checking many scenes that share meshes (a sequence's frames) parses each once. Thread-safe.
class ObjParseCache {
 public:
  /// The parse of `file`, if one was kept.
  std::shared_ptr<const ParsedObj> find(const std::filesystem::path& file) const;
  /// Keeps the parse of `file`.
  void keep(const std::filesystem::path& file, std::shared_ptr<const ParsedObj> parsed);

 private:
  mutable std::mutex mu_;
  std::map<std::filesystem::path, std::shared_ptr<const ParsedObj>> parsed_;
};

/// Reads `file` (named `label` in messages, at JSON path `path`). Vertices are transformed by xf, translated and
/// re-expressed in the camera frame in double precision (see core/render/camera_frame.h), then rounded once to float.
/// Malformed files, and files over the options' AssetLimits (checked before the file is parsed), are SceneErrors;
/// degenerate input is a warning through `json`.
ObjMesh load_obj(const std::filesystem::path& file, const std::string& label, const glm::dmat4& xf,
                 const glm::dvec3& translate, const CameraFrame& frame, SceneJson& json, const std::string& path);

}  // namespace tessera
