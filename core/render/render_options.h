// What to render: the options of render(), as a value the farm's protocol and the command line fill in.
#pragma once

#include "core/image/pixel_window.h"
#include "core/render/layers.h"
#include "core/sampling/adaptive.h"

#include <atomic>
#include <cstdint>
#include <functional>

namespace tessera {

struct Image;
class RayRecorder;
struct RenderState;
struct StoredRender;

/// Progress of a render, reported after each finished tile.
struct RenderProgress {
  int tiles_done = 0;       ///< Tiles finished.
  int tiles_total = 0;      ///< Tiles in the window.
  uint64_t rays = 0;        ///< Rays traced so far.
  double seconds = 0.0;     ///< Wall time so far.
};

/// What to render.
struct RenderOptions {
  uint64_t seed = 0;                 ///< Sample seed; pixels are a pure function of (seed, x, y, sample index).
  uint32_t spp = 0;                  ///< Samples per pixel (0: the scene's).
  PixelWindow window;                ///< Pixels to render (empty: the whole image); row 0 is the top.
  int tile_size = 16;                ///< Edge of the square tiles the window is cut into for threads.
  bool variance = false;             ///< Also write variance-of-the-mean channels and a sample count.
  /// Output layers written beside the colour as extra channels of the image (core/render/layers.h; Layer::kVariance
  /// is `variance`). They never change the colour: the first-hit layers come from a pass of their own over each
  /// pixel's camera rays once its samples are taken (core/render/layer_film.h).
  LayerSet layers;
  /// Adaptive sampling: when > 0, each pixel is sampled in doubling rounds (min_spp, 2 min_spp, ... up to
  /// max_spp) until its relative standard error on luminance falls to target_error (see core/sampling/adaptive.h);
  /// spp is then ignored. The decision uses only the pixel's own samples, so tiling never changes a bit.
  float target_error = 0.f;
  uint32_t min_spp = kAdaptiveMinSpp;  ///< First round of adaptive sampling (also the fewest samples a pixel gets).
  uint32_t max_spp = kAdaptiveMaxSpp;  ///< Most samples a pixel gets with adaptive sampling.
  float error_floor = 0.01f;         ///< Luminance below which adaptive sampling measures absolute error instead.
  /// Independent replicates per pixel (1 = one stratified sequence, the default). K >= 2 interleaves K independently
  /// scrambled sequences so that the variance channels and the adaptive rule use an unbiased error estimate, at
  /// some cost in stratification (see core/sampling/adaptive.h and docs/speed-vs-error.md).
  uint32_t replicates = 1;
  std::function<void(const RenderProgress&)> progress;  ///< Called (from worker threads, serialised) per tile.
  /// Stops early when set, after the pixels in progress (the result is then partial: see RenderResult::state).
  const std::atomic<bool>* cancel = nullptr;
  /// Renders at most this many tiles (0: all), then stops as if cancelled; any tile counts, finished before or not.
  int tile_budget = 0;
  /// Also return every pixel's exact accumulator (RenderResult::state.sums), so the result can be refined later.
  bool keep_state = false;
  /// Resume or refine an earlier render of the same scene, window, seed and sampling options. A pixel that has all
  /// its samples (spp; with adaptive sampling, any) is copied from it; one with fewer continues from its exact
  /// accumulator, which must then be kept (previous->state.exact()); one with none is rendered. Pixels come out bit
  /// for bit as from an uninterrupted render at spp. Requirements (checked, std::invalid_argument): previous's image
  /// has the window's size (and the variance channels when `variance` is set), no pixel has more than spp samples,
  /// keep_state needs an exact previous state, and adaptive sampling cannot continue a pixel.
  const StoredRender* previous = nullptr;
  /// When set, receives every ray the colour's samples trace, from the render's threads (see
  /// core/render/ray_recorder.h; the layers' pass is neither recorded nor counted); pixels are the same.
  RayRecorder* recorder = nullptr;
  /// When set, told as soon as rows of the window are final, e.g. to compress them into a file while the render
  /// goes on: rows [y0, y1) (0 = the window's first row) of `film` (the result's image as the render fills it) and
  /// `state` (its RenderState: samples, and the accumulators with keep_state) hold their final values. Calls come in
  /// order of rows from row 0, never two at once, from the thread that finished the rows' last tile, while the
  /// other threads go on rendering. Rows of a tile stopped by `cancel` or `tile_budget` are never told, nor any
  /// after them. An exception it throws ends the render (render() rethrows it).
  std::function<void(const Image& film, const RenderState& state, int y0, int y1)> rows_final;
};

}  // namespace tessera
