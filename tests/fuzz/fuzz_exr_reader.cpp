// libFuzzer target: bytes through decode_exr, the reader of textures, environment maps, resume files and tile
// states (OpenEXRCore for the common scanline files, OpenEXR's C++ library for the rest and for what OpenEXRCore
// declines). An ImageError is a clean refusal; anything else is a finding. What is read must have the shape the
// header promised.
#include "core/image/image.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const tessera::ExrImage img = tessera::decode_exr(std::string_view(reinterpret_cast<const char*>(data), size));
    const size_t n = size_t(img.pixels.width) * size_t(img.pixels.height);
    if (img.pixels.width != img.data_window.width() || img.pixels.height != img.data_window.height() ||
        img.pixels.rgb.size() != 3 * n)
      std::abort();
    for (const auto& [name, values] : img.pixels.extra)
      if (values.size() != n) std::abort();
    for (const auto& [name, values] : img.pixels.uint_extra)
      if (values.size() != n) std::abort();
  } catch (const tessera::ImageError&) {
  }
  return 0;
}
