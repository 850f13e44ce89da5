// libFuzzer target: an OBJ file's bytes through the scene loader's OBJ reader (a fixed scene with one mesh object,
// transformed and used as an emitter so the area-light split runs too). The bytes go to a file in a per-process
// scratch folder because the loader reads assets by path. A SceneError is a clean refusal; anything else is a finding.
#include "core/scene/scene_loader.h"
#include "tests/fuzz/scratch_dir.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const tessera::fuzz::ScratchDir scratch("obj");
  static const fs::path file = scratch.path / "a.obj";
  static const nlohmann::json scene = nlohmann::json::parse(R"({
    "film": {"resolution": [4, 4]},
    "textures": {"w": {"type": "constant", "color": [0.5, 0.5, 0.5]}},
    "materials": {"m": {"type": "diffuse", "texture_name": "w"}},
    "objects": [{"type": "mesh", "path": "a.obj", "material_name": "m",
                 "transform": [[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0.5, 1]]},
                {"type": "mesh", "path": "a.obj", "translate": [0, 1, 0], "light": {"radiance": [1, 1, 1]}}]})");
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    if (!out) std::abort();
  }
  try {
    (void)tessera::load_scene_json(scene, "fuzz", [&](const std::string&, const std::string&) { return file; });
  } catch (const tessera::SceneError&) {
  }
  return 0;
}
