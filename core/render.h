// Rendering a window of the image with the direct integrator, tile by tile on all threads.
#pragma once

#include "core/image.h"
#include "core/integrator.h"
#include "core/scene.h"

#include <atomic>
#include <cstdint>
#include <functional>

namespace tessera {

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
  std::function<void(const RenderProgress&)> progress;  ///< Called (from worker threads, serialised) per tile.
  const std::atomic<bool>* cancel = nullptr;            ///< Stops early when set (the result is then partial).
};

/// A rendered window.
struct RenderResult {
  Image image;          ///< window.width() x window.height() pixels (+ extra channels when requested).
  PixelWindow window;   ///< Where the image lies in the full picture.
  RayCounters counters; ///< Ray counts.
  double seconds = 0;   ///< Wall time.
  bool cancelled = false;  ///< True when stopped by `cancel`.
};

/// Renders options.window of the scene. Bitwise identical pixels for any window split, tile size or thread count.
RenderResult render(const Scene& scene, const RenderOptions& options);

/// Renders one pixel's samples in a fixed order; returns the mean and (optionally) the variance of the mean.
struct PixelEstimate {
  Vec3 mean;      ///< Average of the samples.
  Vec3 var_mean;  ///< Sample variance divided by the sample count.
};
PixelEstimate render_pixel(const Scene& scene, int px, int row, uint64_t seed, uint32_t spp, RayCounters& counters);

}  // namespace tessera
