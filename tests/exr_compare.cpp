// exr_compare A.exr B.exr: exit 0 when both files hold bitwise identical pixels in every channel, with the same
// channel list (names, pixel types, sampling), windows and metadata, apart from the attributes tests/exr_diff.h
// allows to differ (storage and provenance: compression, render times, job ids...); otherwise prints every
// difference and exits 1 (2 when a file cannot be read). exr_compare --half FLOAT.exr HALF.exr: exit 0 when HALF's
// colours are FLOAT's rounded to half, pixel for pixel. Used by the farm and deploy tests.
#include "core/image/image.h"
#include "tests/exr_diff.h"

#include <Imath/half.h>

#include <cstdio>
#include <exception>
#include <string>

namespace {

int compare_half(const char* full, const char* rounded) {
  const tessera::Image a = tessera::read_exr(full).pixels, b = tessera::read_exr(rounded).pixels;
  if (a.width != b.width || a.height != b.height || a.rgb.size() != b.rgb.size()) {
    std::fprintf(stderr, "%s is %dx%d, %s is %dx%d\n", full, a.width, a.height, rounded, b.width, b.height);
    return 1;
  }
  size_t wrong = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i)
    if (float(half(a.rgb[i])) != b.rgb[i] && ++wrong <= 5)
      std::fprintf(stderr, "value %zu: %g rounds to %g, not %g\n", i, double(a.rgb[i]), double(float(half(a.rgb[i]))),
                   double(b.rgb[i]));
  if (wrong) return 1;
  std::printf("the half copy is the float one rounded (%zu values)\n", a.rgb.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 4 && std::string(argv[1]) == "--half") {
    try {
      return compare_half(argv[2], argv[3]);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 2;
    }
  }
  if (argc != 3) {
    std::fprintf(stderr, "usage: exr_compare A.exr B.exr, or exr_compare --half FLOAT.exr HALF.exr\n");
    return 2;
  }
  try {
    const auto diffs = tessera::testing::exr_differences(argv[1], argv[2]);
    for (const auto& d : diffs) std::fprintf(stderr, "%s\n", d.c_str());
    if (!diffs.empty()) return 1;
    std::printf("identical\n");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
}
