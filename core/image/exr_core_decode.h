// Scanline OpenEXR files decoded with OpenEXRCore, the OpenEXR project's C library, for read_exr's common case.
// OpenEXR's C++ InputFile decodes a ZIP file's blocks through byte-by-byte predictor and interleave loops and hands
// each block to its thread pool; OpenEXRCore decodes the same bytes two to three times as fast on one thread (the
// course's 512x512 half texture: 19 ms against 6 ms, its 1024x512 float sky: 38 ms against 18 ms, on the 2-core VM).
#pragma once

#include "core/image/image.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace tessera::exr_core {

/// Where one channel's values go: `first` is the data window's first pixel, the next pixel `pixel_stride` bytes on
/// and the next row `line_stride` bytes on; 32-bit floats (HALF and FLOAT channels), or 32-bit unsigned integers
/// (a UINT channel, `uint` true).
struct ChannelTarget {
  std::string name;           ///< The channel's name in the file.
  std::byte* first = nullptr;  ///< Where the data window's first pixel goes.
  bool uint = false;           ///< The channel is UINT (else HALF or FLOAT, decoded to float).
  size_t pixel_stride = 0;     ///< Bytes from one pixel to the next.
  size_t line_stride = 0;      ///< Bytes from one row to the next.
};

/// A single-part scanline OpenEXR file held in memory that OpenEXRCore decodes: opened only when every block the
/// data window needs is listed in the file's offset table and lies inside the file, so callers allocate the pixels
/// only for a file that holds its blocks (as OpenEXR's InputFile::isComplete tells). Not copyable; `bytes` must
/// outlive it.
class ScanlineDecoder {
 public:
  /// The decoder of `bytes`, whose data window must be `window`; null when the file is not one it decodes (tiled,
  /// multi-part or deep; a compression other than none, ZIPS or ZIP; another data window) or lacks a block. The
  /// caller then uses OpenEXR's C++ library, whose verdict and message stand.
  static std::unique_ptr<ScanlineDecoder> open(std::string_view bytes, const PixelWindow& window);
  ~ScanlineDecoder();
  ScanlineDecoder(const ScanlineDecoder&) = delete;
  ScanlineDecoder& operator=(const ScanlineDecoder&) = delete;

  /// Decodes the `targets` channels; false when a target channel is missing, subsampled or of another kind than
  /// `uint` says, or when OpenEXRCore reports an error (a damaged block), after which the targets may hold anything.
  /// Large images are decoded a band of blocks per task (oneTBB); the values do not depend on how.
  bool decode(std::span<const ChannelTarget> targets);

 private:
  struct Impl;
  explicit ScanlineDecoder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// ScanlineDecoder::open(bytes, window) and decode(targets) in one call; false when either declines.
bool decode_scanlines(std::string_view bytes, const PixelWindow& window, std::span<const ChannelTarget> targets);

}  // namespace tessera::exr_core
