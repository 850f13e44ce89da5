// Merging tiles into a job's image: validating uploaded tile EXRs, copying them in, writing the result and previews.
#pragma once

#include "core/image/image.h"
#include "core/render/layers.h"
#include "server/preview.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// An uploaded tile after validation: its pixels, or why it was refused.
struct TileCheck {
  std::optional<std::string> error;  ///< Why the tile is invalid (nothing when valid).
  Image pixels;  ///< The tile's RGB pixels (window-sized) and its output layers' channels (extra) when valid.
};

/// Decodes an uploaded tile EXR (its bytes, in memory) and checks it: float32 R, G, B channels and every channel of
/// `layers` (the job's output layers, core/render/layers.h), display window exactly [0,width) x [0,height), data
/// window exactly `window`, every colour value finite. Only the colour and the layers' channels are kept. Never
/// throws for bad input; the error says what is wrong.
TileCheck check_tile_exr(std::string_view exr, const PixelWindow& window, int width, int height,
                         const std::vector<std::string>& layers = {});

/// A validated tile's pixels as stored bytes, in native byte order (little-endian on every machine the farm runs
/// on): its float32 RGB rows (width x height x 12 bytes), then each of `layers`' channels in that order (width x
/// height x 4 bytes each). Without layers the bytes are the tile's own; otherwise they are put together in `buffer`.
std::string_view tile_bytes(const Image& tile, const std::vector<std::string>& layers, std::string& buffer);

/// The stored bytes of a tile without layers: its float32 RGB rows.
inline std::string_view tile_bytes(const Image& tile) {
  return std::string_view(reinterpret_cast<const char*>(tile.rgb.data()), tile.rgb.size() * sizeof(float));
}

/// The inverse of tile_bytes for a width x height tile; throws std::invalid_argument when the size does not match.
Image tile_from_bytes(std::string_view bytes, int width, int height, const std::vector<std::string>& layers = {});

/// One job's float image, filled tile by tile. Thread-safe.
class JobImage {
 public:
  /// A black width x height image with the channels of `layers` beside the colour; its memory is allocated on the
  /// first paste.
  JobImage(int width, int height, std::vector<std::string> layers = {});
  /// Allocates the pixels (zeroed) now, if they are not yet, instead of at the first paste.
  void allocate();
  /// Copies a window-sized tile (its colour and layer channels) into the image; throws std::invalid_argument when it
  /// does not fit.
  void paste(const Image& tile, const PixelWindow& window);
  /// Names the image's pixels as they are now: it changes with every paste, and no two images (of any job) ever share
  /// a value, so a preview made after reading it shows at least the tiles pasted before.
  uint64_t generation();
  /// An sRGB PNG of the image as far as it is filled (black elsewhere), scaled down by a whole factor to at most
  /// kMaxPreviewSide pixels on its long side; a job with no tile yet costs only the PNG's pixels.
  std::vector<uint8_t> preview_png();
  /// The same of an output layer of the job (server/layer_preview.h); throws std::invalid_argument when the image
  /// has no such layer.
  std::vector<uint8_t> layer_preview_png(Layer layer);
  /// Writes the image to `file` as an uncompressed float32 EXR, its layer channels included, with string metadata (and UINT channels, e.g. a
  /// resumable job's state channels), straight from the image (a finished 4K frame is 100 MB: no copy of it is made
  /// in memory); throws ImageError naming the file.
  void write_exr(const std::filesystem::path& file, const std::map<std::string, std::string>& metadata,
                 const std::map<std::string, std::vector<uint32_t>>& uint_channels = {});
  /// Frees the pixels (after the result is written).
  void release();

 private:
  void allocate_locked();
  int width_, height_;
  std::vector<std::string> layers_;
  std::mutex mu_;
  Image image_;
  uint64_t generation_;
};

}  // namespace tessera::server
