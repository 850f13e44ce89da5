// libFuzzer target: a scene file's text through the scene loader. Every asset path resolves to one small valid
// file of its kind (an OBJ quad or a 2x2 EXR), so the fuzzer explores the JSON side; any SceneError is a clean
// refusal, anything else (another exception, a crash, UB, a leak) is a finding.
#include "core/image/image.h"
#include "core/scene/scene_loader.h"
#include "tests/fuzz/scratch_dir.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string_view>

namespace fs = std::filesystem;

namespace {

// Writes the two assets once per process into a private scratch folder.
struct Assets {
  tessera::fuzz::ScratchDir scratch{"scene"};
  fs::path obj = scratch.path / "quad.obj";
  fs::path exr = scratch.path / "tex.exr";
  Assets() {
    std::ofstream(obj) << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
    tessera::Image img = tessera::Image::make(2, 2);
    img.set(1, 0, tessera::Vec3(1.f, 0.5f, 0.25f));
    tessera::write_exr(exr, img);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Assets assets;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const tessera::AssetResolver resolve = [](const std::string& rel, const std::string& jp) -> fs::path {
    if (rel.ends_with(".obj")) return assets.obj;
    if (rel.ends_with(".exr")) return assets.exr;
    throw tessera::SceneError(jp + ": no such asset '" + rel + "'");
  };
  tessera::LoadOptions options;
  options.force_direct = size % 2 == 1;  // both integrator policies
  try {
    const tessera::LoadedScene loaded = tessera::load_scene_text(text, "fuzz.json", resolve, options);
    if (loaded.scene.width <= 0 || loaded.scene.height <= 0) std::abort();  // a loaded scene always has a film
  } catch (const tessera::SceneError&) {
  }
  return 0;
}
