// Rendering a window of the image with the scene's integrator, tile by tile on all threads.
#pragma once

#include "core/sampling/adaptive.h"
#include "core/image/image.h"
#include "core/render/integrator.h"
#include "core/render/render_options.h"
#include "core/render/render_state.h"
#include "core/render/scene.h"

#include <atomic>
#include <cstdint>
#include <functional>

namespace tessera {

/// A rendered window.
struct RenderResult {
  Image image;          ///< window.width() x window.height() pixels (+ extra channels when requested).
  PixelWindow window;   ///< Where the image lies in the full picture.
  RayCounters counters; ///< Ray counts.
  double seconds = 0;   ///< Wall time.
  double parallel_seconds = 0;  ///< Wall time of the threaded part (the rest, seconds - this, is film set-up).
  /// Thread time without a tile during the threaded part, summed over the threads the render could use: the tail
  /// of the last tiles, and any thread that never joined. 0 is perfect; threads x parallel_seconds is all idle.
  double idle_thread_seconds = 0;
  int threads = 1;      ///< Threads the render could use (the task arena's concurrency).
  bool cancelled = false;  ///< True when stopped by `cancel` or `tile_budget` (some pixels are then unfinished).
  /// Samples of every pixel (0: not rendered, when cancelled) and, with keep_state, the exact accumulators.
  RenderState state;
};

/// Renders options.window of the scene. Bitwise identical pixels for any window split, tile size or thread count.
/// Threads take tiles in row-major order (the next free tile), so rows finish roughly from the top down.
RenderResult render(const Scene& scene, const RenderOptions& options);

/// The sampler of sample s of pixel (px, row): with K replicates, sample s / K of replicate s mod K.
PixelSampler pixel_sampler(uint64_t seed, int px, int row, uint32_t s, uint32_t replicates);

/// Renders one pixel's samples 0..spp-1 in order; returns the mean, the variance of the mean and the count.
PixelEstimate render_pixel(const Scene& scene, int px, int row, uint64_t seed, uint32_t spp, RayCounters& counters,
                           uint32_t replicates = 1);

/// Renders one pixel adaptively (samples 0, 1, 2, ... in order, in rounds; see AdaptiveOptions).
PixelEstimate render_pixel_adaptive(const Scene& scene, int px, int row, uint64_t seed, const AdaptiveOptions& opt,
                                    RayCounters& counters);

}  // namespace tessera
