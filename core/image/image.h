// Float images and their files: OpenEXR read/write with windows, extra channels and metadata, sRGB PNG previews.
#pragma once

#include "core/image/pixel_window.h"
#include "core/util/math.h"

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

/// Any failure to read, write or encode an image; the message names the file (when there is one) and the reason.
struct ImageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A float RGB image (row-major, first row = top), optionally with extra named float channels of the same size.
struct Image {
  int width = 0;   ///< Columns.
  int height = 0;  ///< Rows.
  std::vector<float> rgb;  ///< 3 * width * height floats, RGB interleaved.
  /// Further channels (e.g. "variance.R", "samples"), each width * height floats.
  std::map<std::string, std::vector<float>> extra;
  /// Further 32-bit unsigned integer channels (e.g. a resumable render's state, core/render/render_state.h), each
  /// width * height values; written and read as EXR UINT channels, so every bit survives.
  std::map<std::string, std::vector<uint32_t>> uint_extra;

  /// The colour of pixel (x, y); x, y must lie inside the image.
  Vec3 at(int x, int y) const {
    const size_t i = index(x, y);
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
  /// Sets the colour of pixel (x, y); x, y must lie inside the image.
  void set(int x, int y, const Vec3& c) {
    const size_t i = index(x, y);
    rgb[i] = c.x;
    rgb[i + 1] = c.y;
    rgb[i + 2] = c.z;
  }
  /// A zero-filled image without extra channels; throws ImageError for negative sizes.
  static Image make(int width, int height);

 private:
  size_t index(int x, int y) const {
    assert(x >= 0 && x < width && y >= 0 && y < height);
    return 3 * (size_t(y) * size_t(width) + size_t(x));
  }
};

/// Rows [y0, y1) of img as an image of their own, extra channels included; throws ImageError unless
/// 0 <= y0 <= y1 <= img.height.
Image image_rows(const Image& img, int y0, int y1);

/// An EXR as read: its pixels over its data window, the display window and string/int/double metadata.
struct ExrImage {
  Image pixels;                ///< Exactly the data window's pixels.
  PixelWindow data_window;     ///< Where the pixels lie in EXR pixel space.
  PixelWindow display_window;  ///< The picture's frame; the data window may lie partly or wholly outside it.
  std::map<std::string, std::string> metadata;  ///< Header attributes of type string, int or double, as text.
};

/// The most pixels read_exr decodes (and the default of ExrReadOptions::max_pixels).
inline constexpr uint64_t kMaxExrPixels = uint64_t(1) << 28;

/// What read_exr may decode; the bounds are checked from the header, before any pixel is allocated.
struct ExrReadOptions {
  uint64_t max_pixels = kMaxExrPixels;  ///< Largest data window area; kMaxExrPixels bounds it in any case.
  bool colour_only = false;             ///< Decode only the colour: extra channels are neither allocated nor read.
};

/// What read_exr throws for a data window over ExrReadOptions::max_pixels: the message names the file, the window's
/// size and the bound, which are also given as numbers.
struct ExrTooLarge : ImageError {
  ExrTooLarge(const std::string& what, int64_t width, int64_t height, uint64_t limit)
      : ImageError(what), width(width), height(height), limit(limit) {}
  int64_t width;   ///< The data window's width, as the header declares it.
  int64_t height;  ///< Its height.
  uint64_t limit;  ///< The bound on width x height it exceeds.
};

/// Reads the first part of an EXR (scanline or tiled, half/float/uint) with R,G,B channels, or Y (grey; with RY,BY
/// as luminance/chroma). Other full-resolution channels go to pixels.extra (half and float ones) or pixels.uint_extra
/// (UINT ones, exactly), unless options.colour_only; subsampled extra channels are skipped.
/// Pixel values are returned as stored, non-finite ones included. Throws ExrTooLarge for a data window over
/// options.max_pixels, and ImageError (naming the file) for a missing, unreadable, truncated or non-EXR file, deep data,
/// no colour channels, or a data window over 65536 pixels per side.
ExrImage read_exr(const std::filesystem::path& path, const ExrReadOptions& options = {});

/// How an EXR channel's values are stored.
enum class ExrPixelType { kHalf, kFloat, kUint };

/// An EXR's first header, read without decoding a pixel.
struct ExrHeader {
  PixelWindow data_window;                            ///< Where the pixels lie in EXR pixel space.
  PixelWindow display_window;                         ///< The picture's frame.
  std::map<std::string, std::string> metadata;        ///< As ExrImage::metadata.
  std::map<std::string, ExrPixelType> channels;       ///< Every channel's name and pixel type.
};

/// Reads the first header of the EXR at `path`, checked as read_exr checks it before decoding (the bounds on its
/// attributes, the data window within kMaxExrPixels), and decodes no pixel; whether the pixels read is not told.
/// Throws ImageError naming the file.
ExrHeader read_exr_header(const std::filesystem::path& path);

/// read_exr for a file's bytes held in memory (e.g. received over HTTP); throws as read_exr does.
ExrImage decode_exr(std::string_view bytes, const ExrReadOptions& options = {});

/// Lossless compression of an EXR's pixels. Rendered float data is noisy and barely compresses (measured on a 3840x2160
/// float frame: ZIP 7.4 s for 5% smaller, PIZ 5.0 s for 23% smaller, none 0.19 s), so the farm's hot paths use kNone.
enum class ExrCompression {
  kZip,   ///< zlib over 16 scanlines (the default).
  kPiz,   ///< Wavelet + Huffman: smaller on noisy data, slower to decode.
  kNone,  ///< Uncompressed: fastest to write and read.
};

/// How write_exr lays out the file.
struct ExrWriteOptions {
  ExrCompression compression = ExrCompression::kZip;  ///< Pixel compression.
  /// Store R,G,B as 16-bit half, rounded to nearest (beyond +-65504 they become infinite); extra channels stay float.
  bool half = false;
  PixelWindow display_window{};  ///< The picture's frame; empty means the data window.
  PixelWindow data_window{};     ///< Where the pixels go; empty means [0,width) x [0,height), else its size must match.
  /// Written as string attributes; the EXR layout attributes and standard attributes of other types are refused.
  std::map<std::string, std::string> metadata{};
  bool write_extra = true;  ///< Also write the image's extra channels (extra as float, uint_extra as UINT).
};

/// Writes img as a scanline EXR (compressed as opt.compression says): R,G,B (float, or half) plus the extra channels and metadata. Atomic:
/// the bytes go to path + ".tmp", which is synced and renamed over path, so path is never seen half-written. Throws
/// ImageError naming the file; on failure path is untouched and no .tmp file is left.
void write_exr(const std::filesystem::path& path, const Image& img, const ExrWriteOptions& opt = {});

/// The bytes write_exr would write, in memory (e.g. for an HTTP upload); throws ImageError.
std::vector<uint8_t> encode_exr(const Image& img, const ExrWriteOptions& opt = {});

/// img tone-mapped to 8-bit sRGB, R,G,B per pixel row by row: each value times exposure, clamped to [0,1] (NaN -> 0),
/// sRGB-encoded and rounded. Throws ImageError for a malformed image.
std::vector<uint8_t> srgb8_pixels(const Image& img, float exposure = 1.f);

/// The bytes of an 8-bit sRGB PNG of img: its srgb8_pixels. Throws ImageError for an empty or malformed image.
std::vector<uint8_t> encode_png_srgb(const Image& img, float exposure = 1.f);

/// Writes encode_png_srgb(img, exposure) to path, atomically like write_exr. Throws ImageError naming the file.
void write_png_srgb(const std::filesystem::path& path, const Image& img, float exposure = 1.f);

}  // namespace tessera
