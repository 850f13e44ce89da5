// The pieces of a single-part scanline OpenEXR file that Tessera writes itself (exr_uncompressed.h, exr_zip.h): a
// frame buffer's lines packed as the file stores them, the file's start, and its chunks. Internal to core/image.
#pragma once

#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace tessera::exr_scanline {

/// A frame buffer's slices in the order a file of its header stores them (its channels, by name).
class Lines {
 public:
  /// The lines of `frame` under `header`, or nothing for a layout these writers leave to OpenEXR: a tiled, typed or
  /// previewed header, another line order than increasing y, a subsampled channel, a channel without a slice of its
  /// own type, or a line of 2 GiB or more.
  static std::optional<Lines> of(const Imf::Header& header, const Imf::FrameBuffer& frame);

  /// Bytes of one line in the file.
  size_t line_bytes() const { return line_bytes_; }

  /// Copies line y (in the data window) to out, which has line_bytes() bytes: each channel's values in turn, little
  /// endian.
  void pack(int64_t y, char* out) const;

 private:
  struct Plane {
    const char* base;
    size_t x_stride, y_stride, bytes;  // bytes per value in the file (as in memory: same type)
  };
  std::vector<Plane> planes_;
  size_t line_bytes_ = 0;
  int64_t x0_ = 0;
  size_t width_ = 0;
};

/// Writes the file's magic number, its version (with the long-names flag when a name needs it, as OpenEXR decides
/// it) and the header. Throws as Imf::Header::sanityCheck does for a header OpenEXR would not write.
void write_start(Imf::OStream& os, const Imf::Header& header);

/// Writes the line offset table, at os.tellp(), of chunks with these data sizes (each chunk also carries 8 bytes: its
/// first line and its size) written right after it.
void write_offset_table(Imf::OStream& os, const std::vector<size_t>& data_bytes);

/// Writes the line offset table for chunks of the given data (write_offset_table), then each chunk: its first line
/// y0 + i * lines_per_chunk, its size, its data.
void write_chunks(Imf::OStream& os, int64_t y0, int lines_per_chunk, const std::vector<std::vector<char>>& chunks);

}  // namespace tessera::exr_scanline
