// A job's preview: its frame scaled down by a whole factor to at most kMaxPreviewSide pixels on the long side, made
// row by row, so that neither a job without pixels nor a finished job's stored result is ever held whole in memory.
#pragma once

#include "core/image/image.h"

#include <cstdint>
#include <filesystem>
#include <vector>

namespace tessera::server {

/// The longest side of a job's preview PNG, in pixels.
inline constexpr int kMaxPreviewSide = 1024;

/// Scales a width x height frame down as its rows arrive, top to bottom: by the smallest whole factor f that brings
/// its long side to at most kMaxPreviewSide, each preview pixel the mean of the f x f block it covers (the edge blocks
/// of what they cover). Holds the preview and one row of sums, never the frame.
class PreviewDownsampler {
 public:
  /// A downsampler of a width x height frame (both positive); throws std::invalid_argument otherwise.
  PreviewDownsampler(int width, int height);
  /// The next row of the frame: `width` RGB pixels (3 * width floats). Throws std::logic_error past the last row.
  void add_row(const float* rgb);
  /// Rows added so far.
  int rows() const { return next_row_; }
  /// The preview; rows of the frame never added count as black.
  Image take();

 private:
  void flush_block_row();  // the sums of the current block row, divided, into preview_

  int width_, height_, factor_;
  int next_row_ = 0;
  std::vector<float> sums_;  // RGB sums of the current block row, one per preview column
  Image preview_;
};

/// A width x height frame (`image`, nullptr: black) scaled down as PreviewDownsampler does.
Image preview_image(const Image* image, int width, int height);
/// preview_image as an sRGB PNG (a frame within the bound is encoded as it is).
std::vector<uint8_t> preview_png(const Image* image, int width, int height);

/// Rows of a stored EXR read at once by preview_image_of_exr (and the most it holds of the file's pixels).
inline constexpr int kPreviewReadRows = 16;

/// preview_image of the R, G, B channels of the EXR `file`, whose data window must be [0, width) x [0, height):
/// read kPreviewReadRows scanlines at a time, so that memory holds the preview and those rows, not the frame. Throws
/// ImageError naming the file for one it cannot read or of another size.
Image preview_image_of_exr(const std::filesystem::path& file, int width, int height);
/// preview_image_of_exr as an sRGB PNG.
std::vector<uint8_t> preview_png_of_exr(const std::filesystem::path& file, int width, int height);

}  // namespace tessera::server
