// ZIP-compressed scanline OpenEXR files written directly, their chunks compressed by libdeflate rather than by
// OpenEXR through zlib: the same format (OpenEXR's byte split and delta predictor, then a zlib stream), made in
// 0.4-0.7x the time (bench/exr_zip_vs_openexr.cpp). Needs OpenEXR's headers and library.
#pragma once

#include "core/image/exr_scanline.h"

#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>

#include <cstddef>
#include <cstdint>
#include <vector>

struct libdeflate_compressor;

namespace tessera {

/// Lines per chunk of a ZIP (16) or ZIPS (1) file; 0 for any other compression.
int zip_lines_per_chunk(Imf::Compression c);

/// Makes the data a ZIP or ZIPS file stores for one chunk. Not thread-safe: one per thread.
class ZipChunkCompressor {
 public:
  /// A compressor at zlib's `level` (Imf::Header::zipCompressionLevel; out-of-range values are clamped).
  explicit ZipChunkCompressor(int level);
  ~ZipChunkCompressor();
  ZipChunkCompressor(const ZipChunkCompressor&) = delete;
  ZipChunkCompressor& operator=(const ZipChunkCompressor&) = delete;

  /// The chunk data for `size` raw bytes (the chunk's lines as exr_scanline::Lines packs them): the bytes split into
  /// even and odd positions, delta-coded and deflated into a zlib stream, or the raw bytes themselves when that stream
  /// would not be smaller (as OpenEXR stores such a chunk).
  std::vector<char> compress(const char* raw, size_t size);

 private:
  libdeflate_compressor* compressor_;
  std::vector<uint8_t> predicted_;
};

/// Writes a ZIP or ZIPS single-part scanline file of `header` (at its zipCompressionLevel) with the pixels of
/// `frame`, its chunks compressed on up to `threads` threads (the bytes do not depend on how many). Returns false,
/// having written nothing, for another compression or a layout exr_scanline::Lines::of leaves to OpenEXR. Throws as
/// OutputFile does for a header that fails Imf::Header::sanityCheck, and for the stream's errors.
bool write_zip_exr(Imf::OStream& os, const Imf::Header& header, const Imf::FrameBuffer& frame, int threads);

/// The chunks of a ZIP or ZIPS file compressed as its lines arrive in order (e.g. band by band during a render),
/// then written under a header that may be known only at the end. Not thread-safe: one call at a time.
class ZipChunkStream {
 public:
  /// A stream for files of `header`'s data window, compression (ZIP or ZIPS) and zipCompressionLevel.
  explicit ZipChunkStream(const Imf::Header& header);

  /// Adds lines [y0, y1) of the data window from `lines`; y0 must be the first line not yet added. A chunk is
  /// compressed as soon as its last line is there.
  void add(const exr_scanline::Lines& lines, int64_t y0, int64_t y1);

  /// Lines of the data window added so far.
  int64_t lines_added() const { return added_; }

  /// True when every line is there and `header` has this stream's data window, compression and zipCompressionLevel
  /// (its channels are the caller's to compare).
  bool fits(const Imf::Header& header) const;

  /// Writes the file under `header` (fits(header, ...) must hold): start, offset table, chunks.
  void write(Imf::OStream& os, const Imf::Header& header) const;

 private:
  int64_t y0_, height_;
  Imf::Compression compression_;
  int level_, lines_per_chunk_;
  int64_t added_ = 0;
  size_t line_bytes_ = 0;
  std::vector<char> pending_;  // the raw lines of the chunk being filled
  std::vector<std::vector<char>> chunks_;
  ZipChunkCompressor compressor_;
};

}  // namespace tessera
