#include "core/image/exr_scanline.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfVersion.h>

#include <bit>
#include <cstring>
#include <limits>

namespace tessera::exr_scanline {

namespace {

void put32(Imf::OStream& os, int32_t v) {
  char b[4];
  for (int i = 0; i < 4; ++i) b[i] = char(uint32_t(v) >> (8 * i));
  os.write(b, 4);
}

}  // namespace

std::optional<Lines> Lines::of(const Imf::Header& header, const Imf::FrameBuffer& frame) {
  if (header.lineOrder() != Imf::INCREASING_Y || header.hasTileDescription() || header.hasType() ||
      header.hasPreviewImage())
    return std::nullopt;
  Lines out;
  const Imath::Box2i dw = header.dataWindow();
  out.x0_ = dw.min.x;
  out.width_ = size_t(int64_t(dw.max.x) - dw.min.x + 1);
  for (auto c = header.channels().begin(); c != header.channels().end(); ++c) {  // the file's order: by name
    const Imf::Slice* slice = frame.findSlice(c.name());
    if (!slice || slice->type != c.channel().type || c.channel().xSampling != 1 || c.channel().ySampling != 1 ||
        slice->xSampling != 1 || slice->ySampling != 1 || slice->xTileCoords || slice->yTileCoords)
      return std::nullopt;
    const size_t bytes = c.channel().type == Imf::HALF ? 2 : 4;
    out.planes_.push_back({slice->base, slice->xStride, slice->yStride, bytes});
    out.line_bytes_ += out.width_ * bytes;
  }
  if (out.line_bytes_ > size_t(std::numeric_limits<int32_t>::max())) return std::nullopt;
  return out;
}

void Lines::pack(int64_t y, char* out) const {
  // Values are copied as they lie in memory, which is the file's little-endian order only on such a machine.
  static_assert(std::endian::native == std::endian::little);
  for (const Plane& p : planes_) {
    const char* row = p.base + ptrdiff_t(y) * ptrdiff_t(p.y_stride) + ptrdiff_t(x0_) * ptrdiff_t(p.x_stride);
    if (p.x_stride == p.bytes) {
      std::memcpy(out, row, width_ * p.bytes);
      out += width_ * p.bytes;
    } else if (p.bytes == 4) {  // constant sizes, so each copy is one move rather than a call to memcpy
      for (size_t x = 0; x < width_; ++x, out += 4) std::memcpy(out, row + x * p.x_stride, 4);
    } else {
      for (size_t x = 0; x < width_; ++x, out += 2) std::memcpy(out, row + x * p.x_stride, 2);
    }
  }
}

void write_start(Imf::OStream& os, const Imf::Header& header) {
  header.sanityCheck();  // what OutputFile checks first: it throws for a header it would not write
  put32(os, Imf::MAGIC);
  bool long_names = false;
  for (auto a = header.begin(); a != header.end(); ++a)
    long_names |= std::strlen(a.name()) >= 32 || std::strlen(a.attribute().typeName()) >= 32;
  for (auto c = header.channels().begin(); c != header.channels().end(); ++c) long_names |= std::strlen(c.name()) >= 32;
  put32(os, Imf::EXR_VERSION | (long_names ? Imf::LONG_NAMES_FLAG : 0));
  header.writeTo(os);
}

void write_offset_table(Imf::OStream& os, const std::vector<size_t>& data_bytes) {
  uint64_t at = os.tellp() + uint64_t(data_bytes.size()) * 8;
  std::vector<char> table(data_bytes.size() * 8);
  for (size_t i = 0; i < data_bytes.size(); at += 8 + data_bytes[i], ++i)
    for (int b = 0; b < 8; ++b) table[i * 8 + size_t(b)] = char(at >> (8 * b));
  os.write(table.data(), int(table.size()));
}

void write_chunks(Imf::OStream& os, int64_t y0, int lines_per_chunk, const std::vector<std::vector<char>>& chunks) {
  std::vector<size_t> sizes(chunks.size());
  for (size_t i = 0; i < chunks.size(); ++i) sizes[i] = chunks[i].size();
  write_offset_table(os, sizes);
  for (size_t i = 0; i < chunks.size(); ++i) {
    put32(os, int32_t(y0 + int64_t(i) * lines_per_chunk));
    put32(os, int32_t(chunks[i].size()));
    os.write(chunks[i].data(), int(chunks[i].size()));
  }
}

}  // namespace tessera::exr_scanline
