// exr_compare A.exr B.exr: exit 0 when both files have the same display and data windows and bitwise identical
// R,G,B values; otherwise prints where they differ and exits 1 (2 when a file cannot be read). Used by farm tests.
#include "core/image.h"

#include <cstdio>
#include <cstring>
#include <exception>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: exr_compare A.exr B.exr\n");
    return 2;
  }
  try {
    const tessera::ExrImage a = tessera::read_exr(argv[1]);
    const tessera::ExrImage b = tessera::read_exr(argv[2]);
    auto show = [](const tessera::PixelWindow& w) {
      static char buf[4][64];
      static int next = 0;
      char* s = buf[next++ % 4];
      std::snprintf(s, 64, "[%d,%d)x[%d,%d)", w.x0, w.x1, w.y0, w.y1);
      return s;
    };
    if (!(a.display_window == b.display_window) || !(a.data_window == b.data_window)) {
      std::fprintf(stderr, "windows differ: display %s vs %s, data %s vs %s\n", show(a.display_window),
                   show(b.display_window), show(a.data_window), show(b.data_window));
      return 1;
    }
    size_t differing = 0, first = 0;
    for (size_t i = 0; i < a.pixels.rgb.size(); ++i)
      if (std::memcmp(&a.pixels.rgb[i], &b.pixels.rgb[i], sizeof(float)) != 0 && differing++ == 0) first = i;
    if (differing > 0) {
      const size_t px = first / 3;
      std::fprintf(stderr, "%zu of %zu values differ; first at pixel (%d, %d) channel %zu: %.9g vs %.9g\n", differing,
                   a.pixels.rgb.size(), a.data_window.x0 + int(px % size_t(a.pixels.width)),
                   a.data_window.y0 + int(px / size_t(a.pixels.width)), first % 3, a.pixels.rgb[first],
                   b.pixels.rgb[first]);
      return 1;
    }
    std::printf("identical: %dx%d px\n", a.pixels.width, a.pixels.height);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
}
