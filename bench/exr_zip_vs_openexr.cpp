// Tessera's ZIP writer (core/image/exr_zip.h: libdeflate) against OpenEXR's OutputFile (zlib) on the same header and
// pixels, one thread each, alternating: the time to make a whole file in memory, its bytes, and a check that
// OpenEXR reads Tessera's file back to the same pixels. Images: scenes/cbox_no_light.json rendered at 1 spp (the
// noise of a first pass, which barely compresses) and 64 spp, at 128x128 (the fixed-cost bench's render) and 512x512,
// float colours at level 1 and half colours at level 4, as `tessera render` writes them.
//   ./build/bench/exr_zip_vs_openexr [ROUNDS]      (ROUNDS = 20; the best round of each is printed)
#include "bench/run_environment.h"
#include "core/image/exr_layout.h"
#include "core/image/exr_zip.h"
#include "core/image/image.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"

#include <OpenEXR/ImfOutputFile.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

using namespace tessera;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  const int rounds = argc > 1 ? std::max(1, std::atoi(argv[1])) : 20;
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // both writers on one thread
  std::printf("exr_zip_vs_openexr: commit %s\nmachine: %s, %u logical CPUs, load average %s at start\n",
              bench::commit_description(TESSERA_SOURCE_DIR, TESSERA_CONFIGURE_COMMIT).c_str(), bench::cpu_model().c_str(),
              std::thread::hardware_concurrency(), bench::load_average().c_str());
  std::printf("command: ./build/bench/exr_zip_vs_openexr %d; best of %d alternating rounds, one thread each\n\n", rounds,
              rounds);
  std::printf("%-34s %12s %12s %8s %12s %12s\n", "image", "OpenEXR ms", "Tessera ms", "ratio", "OpenEXR B",
              "Tessera B");
  Scene scene = load_scene_file(std::filesystem::path(TESSERA_SOURCE_DIR) / "scenes" / "cbox_no_light.json",
                                LoadOptions{})
                    .scene;
  for (const int res : {128, 512}) {
    for (const uint32_t spp : {1u, 64u}) {
      scene.width = scene.height = res;
      RenderOptions ro;
      ro.spp = spp;
      const Image img = render(scene, ro).image;
      for (const bool half : {false, true}) {
        ExrWriteOptions o;
        o.half = half;
        const PixelWindow data = exr_layout::data_window(img, o);
        const Imf::Header header = exr_layout::header(img, o, data);
        const exr_layout::Frame frame = exr_layout::frame(img, o, data);
        double best_theirs = 1e30, best_ours = 1e30;
        size_t bytes_theirs = 0, bytes_ours = 0;
        std::vector<uint8_t> ours_file, theirs_file;
        for (int r = 0; r < rounds; ++r) {
          {
            exr_io::MemoryOStream theirs("theirs");
            const auto t0 = std::chrono::steady_clock::now();
            {
              Imf::OutputFile out(theirs, header, 0);
              out.setFrameBuffer(frame.buffer);
              out.writePixels(img.height);
            }
            best_theirs = std::min(best_theirs, seconds_since(t0));
            bytes_theirs = theirs.bytes().size();
            theirs_file = theirs.take();
          }
          {
            exr_io::MemoryOStream ours("ours");
            const auto t0 = std::chrono::steady_clock::now();
            if (!write_zip_exr(ours, header, frame.buffer, 1)) {
              std::fprintf(stderr, "exr_zip_vs_openexr: the ZIP writer declined the layout\n");
              return 1;
            }
            best_ours = std::min(best_ours, seconds_since(t0));
            bytes_ours = ours.bytes().size();
            ours_file = ours.take();
          }
        }
        const auto decoded = [](const std::vector<uint8_t>& f) {
          return decode_exr(std::string_view(reinterpret_cast<const char*>(f.data()), f.size())).pixels.rgb;
        };
        const bool same = decoded(ours_file) == decoded(theirs_file);
        char name[64];
        std::snprintf(name, sizeof name, "%dx%d %u spp, %s", res, res, spp, half ? "half, level 4" : "float, level 1");
        std::printf("%-34s %12.3f %12.3f %8.2f %12zu %12zu%s\n", name, 1e3 * best_theirs, 1e3 * best_ours,
                    best_ours / best_theirs, bytes_theirs, bytes_ours, same ? "" : "  PIXELS DIFFER");
        if (!same) return 1;
      }
    }
  }
  std::printf("\nratio: Tessera's time / OpenEXR's; each pair of files decodes to the same pixels.\n");
  return 0;
}
