#include "cli/render_sequence.h"

#include "cli/existing_render.h"
#include "cli/exit_status.h"
#include "cli/frame_list.h"
#include "cli/interrupt_guard.h"
#include "cli/output_check.h"
#include "cli/progress_bar.h"
#include "cli/render_farm.h"
#include "cli/render_resume.h"

#include "core/image/image.h"
#include "core/scene/checked_files.h"
#include "core/scene/scene_loader.h"

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <system_error>

namespace tessera::cli {

namespace fs = std::filesystem;

namespace {

// Most frames whose scene errors are listed one by one.
constexpr size_t kListedErrors = 10;

// Where a frame's files go: its output, its preview (empty: none) and the file --resume continues it from.
struct FramePaths {
  fs::path output, preview, resume;
};

// What loading a frame's scene told: what a render of it records.
struct FrameScene {
  std::string hash;
  uint32_t spp = 0;  // the scene's, or --spp
  int width = 0, height = 0;
};

// The options that make no sense for a sequence of `frames` frames; empty when none.
std::string option_refusal(const RenderArgs& a, size_t frames) {
  const std::string n = std::to_string(frames);
  if (a.skip_existing && !a.crop.empty()) return "--skip-existing judges whole frames: drop --crop";
  if (frames > 1 && !a.crop.empty())
    return "--crop renders a part of one picture, not of " + n + " frames: crop the frames one by one";
  if (frames > 1 && a.tile_budget > 0)
    return "--tile-budget stops one render after N tiles and does not take " + n +
           " frames: render a frame alone to slice it";
  if (frames > 1 && !a.resume.empty() && a.resume.find('#') == std::string::npos)
    return "--resume " + a.resume + " continues one render; with " + n +
           " frames it takes a pattern with a run of '#' naming each frame's file (usually the -o pattern)";
  return "";
}

// frame_output of `pattern`, with the option that gave it named in its refusal.
fs::path option_path(const char* option, const std::string& pattern, int64_t number, size_t frames) {
  try {
    return frame_output(pattern, number, frames);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string(option) + " " + e.what());
  }
}

// Loads every frame's scene as render_scene will, short of building it (LoadOptions::build): the JSON, its values
// and every asset are read, checked and hashed; an image texture several frames share is decoded once. On all
// threads (--threads). Logs each frame that fails and returns nullopt when one does.
std::optional<std::vector<FrameScene>> check_scenes(const RenderArgs& a, const std::vector<FrameFile>& frames) {
  LoadOptions lo = scene_load_options(a);
  lo.build = false;
  CheckedFiles images;
  lo.checked_files = &images;
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
  std::vector<FrameScene> scenes(frames.size());
  std::vector<std::string> errors(frames.size());
  tbb::parallel_for(size_t(0), frames.size(), [&](size_t i) {
    if (InterruptGuard::interrupted()) return;
    try {
      const LoadedScene loaded = load_scene_file(frames[i].scene, lo);
      const Scene& s = loaded.scene;
      scenes[i] = {s.hash, s.settings.spp, s.width, s.height};
    } catch (const std::exception& e) {
      errors[i] = e.what();
    }
  });
  size_t failed = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (errors[i].empty()) continue;
    if (++failed <= kListedErrors) spdlog::error("frame {}: {}", frames[i].number, errors[i]);
  }
  if (failed > kListedErrors) spdlog::error("... and {} more frames whose scene does not load", failed - kListedErrors);
  if (failed > 0) {
    spdlog::error("{} of {} frames do not load; nothing was rendered", failed, frames.size());
    return std::nullopt;
  }
  return scenes;
}

// The sampling settings of a sequence that --resume continues: those its frame files record, as --resume takes one
// render's from its file (resumed_args), or `given`'s when no file of its frame's scene is there. The spp is --spp
// when given; else a file at another spp than its scene's records an --spp, which then holds for every frame, and a
// file at its scene's spp means each frame at its own. Files of another scene, crops and files that do not read say
// nothing (their frames are rendered again). Throws Refusal when two files record different settings.
RenderArgs settings_from_files(const RenderArgs& given, const std::vector<FrameFile>& frames,
                               const std::vector<FrameScene>& scenes, const std::vector<FramePaths>& paths) {
  RenderArgs s = given;
  std::optional<size_t> source;
  for (size_t i = 0; i < frames.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(paths[i].resume, ec)) continue;
    ExrHeader h;
    try {
      h = read_exr_header(paths[i].resume);
    } catch (const std::exception&) {
      continue;
    }
    const PixelWindow full{0, 0, scenes[i].width, scenes[i].height};
    const auto hash = h.metadata.find("tessera:sceneHash");
    if (hash == h.metadata.end() || hash->second != scenes[i].hash || h.display_window != full ||
        h.data_window != full)
      continue;
    const bool variance = h.channels.count("variance.R") > 0;
    if (!source) {
      ExrImage probe;  // what resumed_args reads: the metadata, the window and whether there are variance channels
      probe.metadata = h.metadata;
      probe.data_window = h.data_window;
      probe.display_window = h.display_window;
      if (variance) probe.pixels.extra["variance.R"];
      RenderArgs r = given;
      r.spp.reset();  // raising the spp is decided frame by frame
      r.resume = paths[i].resume.string();
      try {
        r = resumed_args(r, probe);
      } catch (const Refusal&) {
        continue;  // not a render of `tessera render`
      }
      s.seed = r.seed;
      s.replicates = r.replicates;
      s.target_error = r.target_error;
      s.min_spp = r.min_spp;
      s.max_spp = r.max_spp;
      s.error_floor = r.error_floor;
      s.area_sampling = r.area_sampling;
      s.env_sampling = r.env_sampling;
      s.bvh = r.bvh;
      s.layers = r.layers;
      s.variance = r.variance;
      if (!given.spp && r.target_error <= 0 && r.spp && *r.spp != scenes[i].spp) s.spp = r.spp;
      source = i;
    }
    const std::map<std::string, std::string> expected = sampling_settings(s, s.spp.value_or(scenes[i].spp)).metadata();
    std::string diff = sampling_difference(h.metadata, expected, given.spp ? "tessera:spp" : "");
    if (diff.empty() && variance != s.variance)
      diff = variance ? "variance channels, not none" : "no variance channels, not --variance";
    if (!diff.empty())
      throw Refusal("frame " + std::to_string(frames[i].number) + ": " + paths[i].resume.string() +
                    " was rendered with " + diff + " as frame " + std::to_string(frames[*source].number) + "'s " +
                    paths[*source].resume.string() + " was; --resume continues a sequence with the settings its "
                    "files record, so they must agree: move away the frames rendered otherwise");
  }
  return s;
}

}  // namespace

int run_render_sequence(const RenderArgs& given) {
  InterruptGuard interrupts;  // a signal between two frames stops the sequence before the next one
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<FrameFile> frames;
  std::vector<FramePaths> paths;
  try {
    frames = expand_frames(given.scenes, given.frames);
    const size_t n = frames.size();
    if (const std::string why = option_refusal(given, n); !why.empty()) throw std::invalid_argument(why);
    for (const FrameFile& f : frames) {
      FramePaths p;
      p.output = option_path("-o", given.output, f.number, n);
      if (!given.preview.empty()) p.preview = option_path("--preview", given.preview, f.number, n);
      if (!given.resume.empty()) p.resume = option_path("--resume", given.resume, f.number, n);
      paths.push_back(std::move(p));
    }
  } catch (const std::invalid_argument& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  }
  const size_t n = frames.size();
  if (given.workers > 0 && n > 1) return render_farm_sequence(given, frames);
  for (const FramePaths& p : paths)
    if (!output_writable(p.output) || (!p.preview.empty() && !output_writable(p.preview, "preview")))
      return kExitRefused;
  const std::optional<std::vector<FrameScene>> scenes = check_scenes(given, frames);
  if (!scenes) return kExitRefused;
  if (InterruptGuard::interrupted()) {
    spdlog::warn("interrupted before the first frame; nothing was rendered");
    return kExitInterrupted;
  }

  // Each frame is rendered with these arguments, its own scene and files filled in.
  RenderArgs base = given;
  base.scenes.clear();
  base.frames.clear();
  base.skip_existing = false;
  base.resume.clear();
  const bool resume = !given.resume.empty();
  if (resume) {
    try {
      base = settings_from_files(base, frames, *scenes, paths);
    } catch (const Refusal& e) {
      spdlog::error("{}", e.what());
      return kExitRefused;
    }
  }

  // What takes an interrupted sequence up again: the same command with --resume in place of the sampling options
  // (which --resume takes from the files).
  const std::string again = "--resume " + given.output + " (in place of the sampling options) continues the sequence";
  size_t rendered = 0, skipped = 0;
  for (size_t k = 0; k < n; ++k) {
    const FrameFile& f = frames[k];
    const FramePaths& p = paths[k];
    const std::string name = "frame " + std::to_string(f.number);
    if (InterruptGuard::interrupted()) {
      std::fprintf(stderr, "interrupted: %s and the frames after it were not started; %s\n", name.c_str(),
                   again.c_str());
      return kExitInterrupted;
    }
    RenderArgs a = base;
    a.scene = f.scene.string();
    a.output = p.output.string();
    a.preview = p.preview.string();
    const FrameScene& scene = (*scenes)[k];
    const ExpectedRender expected = expected_render(a, scene.hash, scene.width, scene.height, scene.spp);
    if (given.skip_existing || resume) {
      const ExistingRender out = examine_render(p.output, expected);
      if (out.complete) {
        std::fprintf(stderr, "%s: %s is complete, skipped\n", name.c_str(), p.output.c_str());
        ++skipped;
        continue;
      }
      std::optional<ExistingRender> from;
      if (resume) from = p.resume == p.output ? out : examine_render(p.resume, expected);
      if (from && from->continuable) {
        a.resume = p.resume.string();
        // The spp the frame is rendered at: --spp, or its scene's (a file at fewer spp with exact sums is raised).
        if (a.target_error > 0) a.spp.reset();
        else a.spp = a.spp.value_or(scene.spp);
        std::fprintf(stderr, "%s: continuing %s, which %s\n", name.c_str(), p.resume.c_str(),
                     from->why_incomplete.c_str());
      } else if (from && from->exists) {
        std::fprintf(stderr, "%s: %s %s, rendering it again\n", name.c_str(), p.resume.c_str(),
                     from->why_not_continuable.c_str());
      } else if (out.exists) {
        std::fprintf(stderr, "%s: %s %s, rendering it again\n", name.c_str(), p.output.c_str(),
                     out.why_incomplete.c_str());
      }
    }
    std::fprintf(stderr, "%s (%zu of %zu): %s -> %s\n", name.c_str(), k + 1, n, a.scene.c_str(), a.output.c_str());
    const int rc = render_scene(a);
    if (rc == kExitOk) {
      ++rendered;
      continue;
    }
    if (rc == kExitInterrupted) {
      if (k + 1 < n)
        std::fprintf(stderr, "interrupted: the frames after %s were not started; %s\n", name.c_str(), again.c_str());
      return rc;
    }
    if (rc == kExitBudget) return rc;  // a one-frame sequence (--tile-budget is refused with several)
    if (rc == kExitRefused && rendered == 0) {
      spdlog::error("{} was refused; no frame was written", name);
      return kExitRefused;
    }
    spdlog::error("{} failed; {} frame(s) were written, the frames after it were not started", name, rendered);
    return kExitFailed;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::fprintf(stderr, "%zu frame(s): %zu rendered, %zu skipped as complete, in %s\n", n, rendered, skipped,
               format_duration(seconds).c_str());
  return kExitOk;
}

}  // namespace tessera::cli
