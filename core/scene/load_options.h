// What a scene load may override or skip: the options of load_scene_file, as a value the farm's protocol carries.
#pragma once

#include "core/geometry/split_method.h"
#include "core/render/light_sampling.h"

#include <cstdint>
#include <filesystem>
#include <optional>

namespace tessera {

class CheckedFiles;
class ObjParseCache;

/// Bounds on what one asset file may make the loader allocate, checked before it is decoded: an image texture's size
/// from its header, an OBJ mesh's size from its byte count and a count of its lines (docs/scene-format.md, Asset
/// limits). The defaults are the most the loader reads at all.
struct AssetLimits {
  /// Largest width x height of an image texture's data window (at most 2^28, the most read_exr decodes).
  uint64_t max_pixels = uint64_t(1) << 28;
  /// Most triangles of an OBJ mesh once its faces are split into triangles; it also bounds the file's size
  /// (kObjBytesPerTriangle per triangle) and its vertex positions, normals and texture coordinates (each
  /// kObjVerticesPerTriangle per triangle).
  uint64_t max_triangles = uint64_t(1) << 26;

  /// Field by field.
  bool operator==(const AssetLimits&) const = default;
};

/// How strictly and from where to load.
struct LoadOptions {
  bool strict = false;                           ///< Unknown keys are errors instead of warnings.
  bool force_direct = false;                     ///< Render other integrator types with the direct integrator.
  std::optional<std::filesystem::path> asset_root;  ///< Assets may lie anywhere below this folder (default: the scene's folder).
  std::optional<uint32_t> spp;                   ///< Overrides integrator.spp.
  std::optional<AreaSampling> area_sampling;     ///< Overrides integrator.area_sampling.
  std::optional<EnvSampling> env_sampling;       ///< Overrides integrator.env_sampling.
  std::optional<SplitMethod> bvh;                ///< Overrides integrator.bvh (sah or median).
  bool build = true;  ///< Build the BVH and the lights' tables; false stops after validation (a scene to check, not render).
  AssetLimits asset_limits;  ///< Bounds on each image texture and mesh, checked before it is decoded.
  /// Image textures recorded here as clean are not decoded again (their recorded SHA-256 enters the scene's hash; a
  /// build takes their recorded pixels and decodes those it has no pixels for), and images that decode clean are
  /// recorded, with their pixels when building. Only for asset files never rewritten in place, and always with the same
  /// asset_limits (a recorded image is not measured again).
  CheckedFiles* checked_files = nullptr;
  /// Mesh files recorded here are not read again for their SHA-256 (the recorded one enters the scene's hash), and
  /// meshes read are recorded; a record of its own (a file in checked_files is a clean image). Only for asset files
  /// never rewritten in place.
  CheckedFiles* mesh_digests = nullptr;
  /// OBJ files parsed here are not parsed again (core/scene/obj_mesh.h); for files never rewritten in place, checked
  /// with the same asset_limits.
  ObjParseCache* obj_cache = nullptr;

  /// Field by field.
  bool operator==(const LoadOptions&) const = default;
};

}  // namespace tessera
