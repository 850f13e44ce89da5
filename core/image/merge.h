// Assembling cropped EXR tiles (each a data window inside the full display window) into the full image, with their
// output layers.
#pragma once

#include "core/image/image.h"

#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera {

/// Tiles that cannot be merged: the message lists every problem with the pixel regions concerned.
struct MergeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One tile to merge and the name used for it in messages (usually its file name).
struct MergeInput {
  std::string name;  ///< Shown in error messages.
  ExrImage image;    ///< Its pixels, data window and display window.
};

/// The assembled image.
struct MergeResult {
  Image image;                   ///< display_window.width() x display_window.height() pixels, extra channels included.
  PixelWindow display_window;    ///< The frame shared by all inputs.
  int64_t overlap_pixels = 0;    ///< Pixels supplied by more than one input (all with identical values).
  /// Metadata entries present with the same value in every input (e.g. scene hash, spp, seed).
  std::map<std::string, std::string> metadata;
};

/// Merges the R,G,B channels and the float extra channels (output layers, variance) of tiles that share one display
/// window; every input must have the same extra channels (UINT ones are ignored). Every display-window pixel must
/// come from at least one input; a pixel supplied by several inputs is accepted when all its channels are bitwise
/// identical (a re-rendered tile's are, since pixels are a pure function of the seed and position) and is a conflict
/// otherwise. Throws MergeError listing, as merged rectangles, the pixels covered by no input, the
/// conflicting overlaps per pair of inputs, and any input whose data window leaves the display window or whose
/// display window differs from the first input's.
MergeResult merge_tiles(const std::vector<MergeInput>& inputs);

/// Covers the set pixels of a row-major mask over `frame` with disjoint rectangles: runs of each row, with equal
/// runs of consecutive rows joined; the result is sorted by (y0, x0). Used for readable error messages.
std::vector<PixelWindow> mask_to_rectangles(const std::vector<uint8_t>& mask, const PixelWindow& frame);

/// "[x0,x1) x [y0,y1)" for one window.
std::string format_window(const PixelWindow& w);

/// The rectangles as a comma-separated list of format_window, at most max_listed of them followed by
/// "and N more"; total pixels are appended in parentheses.
std::string format_regions(const std::vector<PixelWindow>& regions, size_t max_listed = 16);

}  // namespace tessera
