// What a render leaves in its EXR so that a later run can finish it (`render --resume`) or refine it to more
// samples: per pixel, the samples taken and, when kept, the pixel's exact accumulator.
#pragma once

#include "core/sampling/adaptive.h"
#include "core/image/image.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace tessera {

/// The UINT channel holding each pixel's sample count; 0 marks a pixel not rendered yet (an interrupted render).
inline constexpr const char* kSamplesChannel = "tessera.samples";
/// Prefix of the exact accumulator's channels: each double `name` of PixelAccumulator::state_names is stored bit
/// for bit as two UINT channels, "tessera.state.<name>.hi" (high 32 bits) and "tessera.state.<name>.lo".
inline constexpr const char* kStateChannelPrefix = "tessera.state.";

/// The per-pixel state of a rendered window (row-major, first row = top).
struct RenderState {
  uint32_t replicates = 1;         ///< Replicates of the accumulators (see PixelAccumulator).
  std::vector<uint32_t> samples;   ///< Samples taken per pixel; 0: not rendered.
  /// Exact accumulators, PixelAccumulator::state_size(replicates) doubles per pixel; empty when not kept.
  std::vector<double> sums;

  /// True when the exact accumulators are kept.
  bool exact() const { return !sums.empty(); }
  /// Pixel i's accumulator (requires exact()).
  PixelAccumulator pixel(size_t i) const;
  /// Stores acc as pixel i's accumulator and sample count (requires exact()).
  void set(size_t i, const PixelAccumulator& acc);
};

/// An earlier render of a window: its image (colours and extra channels as written) and its state.
struct StoredRender {
  Image image;        ///< Pixels of the window.
  RenderState state;  ///< Their state (samples.size() == image.width * image.height).
};

/// Adds state's channels to img (kSamplesChannel, and the accumulator channels when state.exact()). img holds the
/// state's pixels from index `first` on (a band of rows y0.. of the window: first = y0 * width).
void write_state_channels(const RenderState& state, Image& img, size_t first = 0);

/// The state stored in img's channels by write_state_channels for accumulators of `replicates` replicates; the
/// accumulators are read when present. Throws ImageError when the sample channel is missing or the accumulator
/// channels are incomplete.
RenderState read_state_channels(const Image& img, uint32_t replicates);

}  // namespace tessera
