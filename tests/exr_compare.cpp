// exr_compare A.exr B.exr: exit 0 when both files hold bitwise identical pixels in every channel, with the same
// channel list (names, pixel types, sampling), windows and metadata, apart from the attributes tests/exr_diff.h
// allows to differ (storage and provenance: compression, render times, job ids...); otherwise prints every
// difference and exits 1 (2 when a file cannot be read). Used by the farm and deploy tests.
#include "tests/exr_diff.h"

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: exr_compare A.exr B.exr\n");
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
