// The asset limit flags of the commands that load scenes (`render`, `serve`, `worker`): how large an image texture
// or an OBJ mesh may be (core/scene/load_options.h, AssetLimits), checked before the file is decoded.
#pragma once

#include "core/scene/load_options.h"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace tessera::cli {

/// Registers --max-asset-pixels and --max-mesh-triangles on `command`, filling `limits` (their defaults are its).
void add_asset_limit_flags(CLI::App* command, AssetLimits& limits);

/// The same flags with `limits`' values, for a child process (`render --workers` starts a coordinator and workers).
std::vector<std::string> asset_limit_args(const AssetLimits& limits);

}  // namespace tessera::cli
