#include "cli/render_sequence.h"

#include "cli/exit_status.h"
#include "cli/interrupt_guard.h"
#include "cli/output_check.h"
#include "cli/render_farm.h"
#include "cli/sampling_flags.h"
#include "core/image/image.h"
#include "core/scene/scene_loader.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

namespace tessera::cli {

namespace fs = std::filesystem;

std::string incomplete_reason(const RenderArgs& a, const fs::path& scene, const fs::path& output) {
  std::error_code ec;
  if (!fs::exists(output, ec)) return "missing";
  std::map<std::string, std::string> meta;
  try {
    ExrReadOptions ro;
    ro.colour_only = true;
    meta = read_exr(output, ro).metadata;
  } catch (const std::exception& e) {
    return std::string("unreadable (") + e.what() + ")";
  }
  if (const auto p = meta.find("tessera:partial"); p != meta.end()) return "partial (" + p->second + ")";
  LoadOptions lo;
  lo.build = false;
  lo.force_direct = !a.integrator.empty();
  if (!a.asset_root.empty()) lo.asset_root = a.asset_root;
  LoadedScene loaded;
  try {
    loaded = load_scene_file(scene, lo);
  } catch (const std::exception& e) {
    return std::string("not checked: the scene does not load (") + e.what() + ")";
  }
  const auto hash = meta.find("tessera:sceneHash");
  if (hash == meta.end() || hash->second != loaded.scene.hash) return "rendered from another scene or other assets";
  const uint32_t spp = a.spp ? *a.spp : loaded.scene.settings.spp;
  for (const auto& [key, value] : sampling_settings(a, spp).metadata()) {
    const auto it = meta.find(key);
    if (it == meta.end() || it->second != value)
      return "rendered with other settings (" + key + " " + (it == meta.end() ? "absent" : it->second) + ", not " +
             value + ")";
  }
  return "";
}

int render_sequence(const RenderArgs& given, const std::vector<FrameFile>& frames) {
  // Options that name one image's pixels or one file have no meaning for several frames.
  if (!given.crop.empty() || !given.resume.empty() || given.tile_budget > 0) {
    spdlog::error("a sequence renders whole frames: drop --crop, --resume FILE and --tile-budget (--skip-existing "
                  "skips complete frames and continues partial ones)");
    return kExitRefused;
  }
  std::vector<fs::path> outputs, previews;
  try {
    for (const FrameFile& f : frames) {
      outputs.push_back(frame_output(given.output, f.number, frames.size()));
      if (!given.preview.empty()) previews.push_back(frame_output(given.preview, f.number, frames.size()));
    }
  } catch (const std::invalid_argument& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  }
  // Before anything long: outputs that cannot be written are reported now (every frame's folder is the first's).
  if (!output_writable(outputs.front()) || (!previews.empty() && !output_writable(previews.front(), "preview")))
    return kExitRefused;
  if (given.workers > 0) {
    if (given.skip_existing) {
      spdlog::error("--skip-existing renders frames in this process: drop --workers, or render only the frames "
                    "missing (--frames)");
      return kExitRefused;
    }
    std::vector<client::FrameScene> scenes;
    for (const FrameFile& f : frames) scenes.push_back({f.number, f.scene});
    return run_render_farm(given, scenes);
  }
  // Every frame's scene is read before the first is rendered: a broken frame refuses the sequence, not its end.
  for (const FrameFile& f : frames) {
    try {
      LoadOptions lo;
      lo.build = false;
      lo.strict = given.strict;
      if (!given.asset_root.empty()) lo.asset_root = given.asset_root;
      load_scene_file(f.scene, lo);
    } catch (const std::exception& e) {
      spdlog::error("frame {}: {}", f.number, e.what());
      return kExitRefused;
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  size_t rendered = 0, skipped = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    RenderArgs a = given;
    a.scenes = {frames[i].scene.string()};
    a.frames.clear();
    a.scene = frames[i].scene.string();
    a.output = outputs[i].string();
    a.preview = previews.empty() ? std::string() : previews[i].string();
    if (given.skip_existing) {
      const std::string why = incomplete_reason(given, frames[i].scene, outputs[i]);
      if (why.empty()) {
        ++skipped;
        if (!given.quiet) std::fprintf(stderr, "frame %lld: %s is complete, skipped\n",
                                       static_cast<long long>(frames[i].number), a.output.c_str());
        continue;
      }
      if (why.rfind("partial", 0) == 0) a.resume = a.output;  // continued (rendered anew when it cannot be)
      if (why != "missing") spdlog::info("frame {}: {} is {}, rendering it again", frames[i].number, a.output, why);
    }
    if (!given.quiet)
      std::fprintf(stderr, "frame %lld (%zu of %zu): %s -> %s\n", static_cast<long long>(frames[i].number), i + 1,
                   frames.size(), a.scene.c_str(), a.output.c_str());
    int rc = run_render(a);
    if (rc == kExitRefused && !a.resume.empty()) {  // a partial file of other settings: rendered from the start
      a.resume.clear();
      rc = run_render(a);
    }
    if (rc != kExitOk) {
      if (rc == kExitInterrupted || rc == 3) spdlog::warn("stopped at frame {}; later frames were not started", frames[i].number);
      else spdlog::error("frame {} failed; later frames were not started", frames[i].number);
      return rc;
    }
    ++rendered;
  }
  if (!given.quiet)
    std::fprintf(stderr, "%zu frames rendered, %zu skipped, %.2fs\n", rendered, skipped,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return kExitOk;
}

}  // namespace tessera::cli
