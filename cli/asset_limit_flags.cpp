#include "cli/asset_limit_flags.h"

#include "core/image/image.h"
#include "core/scene/obj_limits.h"

namespace tessera::cli {

void add_asset_limit_flags(CLI::App* command, AssetLimits& limits) {
  command->add_option("--max-asset-pixels", limits.max_pixels,
                      "Largest width x height of an image texture, read from its header before it is decoded "
                      "(larger ones are refused)")
      ->check(CLI::Range(uint64_t(1), kMaxExrPixels))->capture_default_str();
  command->add_option("--max-mesh-triangles", limits.max_triangles,
                      "Most triangles of an OBJ mesh, counted before it is parsed; per triangle also " +
                          std::to_string(kObjVerticesPerTriangle) +
                          " vertex positions, normals and texture coordinates and " +
                          std::to_string(kObjBytesPerTriangle) + " bytes of file (larger meshes are refused)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 40))->capture_default_str();
}

std::vector<std::string> asset_limit_args(const AssetLimits& limits) {
  return {"--max-asset-pixels", std::to_string(limits.max_pixels), "--max-mesh-triangles",
          std::to_string(limits.max_triangles)};
}

}  // namespace tessera::cli
