// `tessera render`: load a scene, render it (or a crop of it) on this machine, write an OpenEXR file; or render a
// sequence of frames, one scene file each (cli/render_sequence.h).
#pragma once

#include "cli/sampling_flags.h"
#include "core/scene/load_options.h"
#include "protocol/sequence.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace tessera::cli {

/// Options of `tessera render` (the sampling ones are those `submit` has too).
struct RenderArgs : SamplingArgs {
  /// Scene files as given: one; several, one per frame (a shell glob's expansion); or one pattern with a run of '#'
  /// that `frames` numbers (cli/frame_list.h).
  std::vector<std::string> scenes;
  std::string frames;                   ///< Frame range of a '#' pattern ("1-240x2,300"); empty: none.
  std::string frame_order = protocol::to_string(protocol::FrameOrder::in_order);  ///< --frame-order with --workers.
  bool skip_existing = false;           ///< Skip frames whose output is a complete render of these settings.
  std::string scene;                    ///< The scene file one render renders: the one input, or a frame's.
  std::string output;                   ///< EXR to write (with several frames, a pattern with a run of '#').
  int threads = 0;                      ///< Threads (0: all cores).
  std::vector<int> crop;                ///< X0 Y0 X1 Y1 (half-open, row 0 = top).
  bool half = false;                    ///< Write half floats.
  bool variance = false;                ///< Write variance and sample-count channels.
  bool multipart = false;               ///< Write one EXR part per output layer.
  std::string preview;                  ///< Also write an sRGB PNG here (with several frames, a '#' pattern).
  bool strict = false;                  ///< Unknown scene keys are errors.
  std::string asset_root;               ///< Allow assets anywhere below this folder.
  int tile_size = 16;                   ///< Thread tile edge.
  bool quiet = false;                   ///< No progress bar.
  bool timing = false;                  ///< Print where the wall time went (load, film, threads, write).
  int workers = 0;                      ///< >0: render through a local coordinator and this many worker processes.
  int farm_tile = 64;                   ///< Farm tile edge (with --workers; the farm's default tile size).
  bool resumable = false;               ///< Also write each pixel's exact accumulator (for a later refinement).
  int tile_budget = 0;                  ///< Render at most this many tiles, then write a partial EXR (0: all).
  std::string resume;                   ///< Finish or refine this earlier render's EXR (several frames: a '#' pattern).
  AssetLimits asset_limits;             ///< How large each image texture and mesh may be (also told to --workers).
};

/// Registers the subcommand's options on `app`.
CLI::App* add_render_command(CLI::App& app, RenderArgs& args);

/// Runs it; returns the process exit code (errors are reported, never thrown): 0 done, 1 failed, 2 refused before
/// rendering, 3 stopped by --tile-budget and 130 interrupted by SIGINT/SIGTERM (both after writing a partial EXR).
/// One input without --frames or --skip-existing is one render (render_scene of that file); anything else is a
/// sequence (run_render_sequence, cli/render_sequence.h). Without inputs, `args.scene` is rendered.
int run_render(const RenderArgs& args);

/// Renders `args.scene` to `args.output` (locally, or through --workers): the one render that `tessera render
/// SCENE -o OUT` is, and that a sequence runs for each of its frames. Returns the exit code as run_render does.
int render_scene(const RenderArgs& args);

/// The scene-loading options `args` ask for (strictness, asset root and limits, spp, integrator and strategy
/// overrides): what render_scene loads its scene with.
LoadOptions scene_load_options(const RenderArgs& args);

}  // namespace tessera::cli
