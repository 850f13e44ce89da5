// Loading scenes in the course format (docs/scene-format.md; examples in scenes/course/) into render-ready Scenes.
#pragma once

#include "core/scene/json_depth.h"
#include "core/scene/load_options.h"

#include "core/render/scene.h"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

class CheckedFiles;

/// A scene that cannot be loaded; the message names the file and the JSON path of the offending value.
struct SceneError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Maps an asset path as written in the scene (and the JSON path naming it) to a readable file.
using AssetResolver = std::function<std::filesystem::path(const std::string& path, const std::string& json_path)>;

/// A loaded scene with what the loader had to say about it.
struct LoadedScene {
  Scene scene;                        ///< The scene, BVH built (unless LoadOptions::build is false).
  std::vector<std::string> warnings;  ///< Unknown keys and degenerate input that was skipped.
  std::vector<std::string> notes;     ///< Settings of other integrators that were ignored.
  std::vector<std::string> assets;    ///< Asset paths the scene uses, as written in it.
  int images_reused = 0;              ///< Image textures taken from LoadOptions::checked_files, not decoded.
  bool environment_reused = false;    ///< The environment map's sampling table taken from there too, not built.
};

/// Loads a scene file; assets resolve against its folder and must stay inside it (or inside asset_root).
LoadedScene load_scene_file(const std::filesystem::path& path, const LoadOptions& options = {});

/// Loads a scene from its JSON text (as read from a file named `name`); malformed or too deeply nested JSON is a
/// SceneError too.
LoadedScene load_scene_text(std::string_view text, const std::string& name, const AssetResolver& resolve,
                            const LoadOptions& options = {});

/// Loads a parsed scene; `name` prefixes messages, `resolve` finds assets.
LoadedScene load_scene_json(const nlohmann::json& scene, const std::string& name, const AssetResolver& resolve,
                            const LoadOptions& options = {});

/// The asset paths a scene uses (meshes, textures referenced by used materials or the environment), as written.
std::vector<std::string> scene_asset_paths(const nlohmann::json& scene);

/// Resolves `rel` against `base` and checks it stays inside `root`; absolute paths are refused unless
/// allow_absolute (an explicit asset root); throws SceneError naming json_path.
std::filesystem::path resolve_inside(const std::filesystem::path& base, const std::filesystem::path& root,
                                     const std::string& rel, const std::string& json_path, bool allow_absolute = false);

}  // namespace tessera
