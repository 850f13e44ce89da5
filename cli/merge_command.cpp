#include "cli/merge_command.h"

#include "cli/exit_status.h"

#include "core/image/exr_multipart.h"
#include "core/image/image.h"
#include "core/image/merge.h"
#include "core/render/layer_film.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace tessera::cli {

CLI::App* add_merge_command(CLI::App& app, MergeArgs& a) {
  auto* c = app.add_subcommand("merge", "Assemble cropped EXR tiles into one image");
  c->add_option("tiles", a.inputs, "Tile EXRs written by 'tessera render --crop' (same display window)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_option("-o,--output", a.output, "Output EXR file (written atomically)")->required();
  c->add_flag("--half", a.half, "Write half floats instead of float32");
  c->add_flag("--multipart", a.multipart,
              "Write a multi-part EXR, one part per output layer (default: one part holding every channel)");
  c->footer(
      "Every pixel of the display window must come from some tile. Tiles may be single- or multi-part EXRs and must "
      "all have the same extra channels (output layers, variance), which are merged with the colour. Tiles may "
      "overlap only where all their channels are bitwise identical (as re-rendered tiles are); any other overlap, "
      "and any gap, is an error listing the pixel rectangles concerned.");
  return c;
}

int run_merge(const MergeArgs& a) {
  // Tiles that cannot be read, or do not make one image, are refused before the output is touched.
  std::vector<MergeInput> inputs;
  MergeResult merged;
  try {
    inputs.reserve(a.inputs.size());
    for (const auto& path : a.inputs) inputs.push_back({path, read_exr_all_parts(path)});
    merged = merge_tiles(inputs);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  }
  try {
    ExrWriteOptions wo;
    wo.half = a.half;
    wo.data_window = merged.display_window;
    wo.display_window = merged.display_window;
    wo.metadata = merged.metadata;
    if (a.multipart) write_exr_multipart(a.output, merged.image, wo, layer_parts(merged.image));
    else write_exr(a.output, merged.image, wo);
  } catch (const std::exception& e) {
    spdlog::error("merge failed: {}", e.what());
    return kExitFailed;
  }
  std::fprintf(stderr, "%s: %dx%d px from %zu tiles", a.output.c_str(), merged.display_window.width(),
               merged.display_window.height(), inputs.size());
  if (merged.overlap_pixels > 0)
    std::fprintf(stderr, " (%lld overlapping pixels, identical)", static_cast<long long>(merged.overlap_pixels));
  std::fputc('\n', stderr);
  return kExitOk;
}

}  // namespace tessera::cli
