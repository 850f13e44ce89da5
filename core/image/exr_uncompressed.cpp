#include "core/image/exr_uncompressed.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfVersion.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

namespace tessera {

bool write_uncompressed_exr(Imf::OStream& os, const Imf::Header& header, const Imf::FrameBuffer& frame) {
  if (header.compression() != Imf::NO_COMPRESSION || header.lineOrder() != Imf::INCREASING_Y ||
      header.hasTileDescription() || header.hasType() || header.hasPreviewImage())
    return false;
  header.sanityCheck();  // what OutputFile checks first: it throws for a header it would not write
  struct Plane {
    const char* base;
    size_t x_stride, y_stride, bytes;  // bytes per value in the file (as in memory: same type)
  };
  std::vector<Plane> planes;
  size_t line_bytes = 0;
  const Imath::Box2i dw = header.dataWindow();
  const size_t width = size_t(int64_t(dw.max.x) - dw.min.x + 1);
  for (auto c = header.channels().begin(); c != header.channels().end(); ++c) {  // the file's order: by name
    const Imf::Slice* slice = frame.findSlice(c.name());
    if (!slice || slice->type != c.channel().type || c.channel().xSampling != 1 || c.channel().ySampling != 1 ||
        slice->xSampling != 1 || slice->ySampling != 1 || slice->xTileCoords || slice->yTileCoords)
      return false;
    const size_t bytes = c.channel().type == Imf::HALF ? 2 : 4;
    planes.push_back({slice->base, slice->xStride, slice->yStride, bytes});
    line_bytes += width * bytes;
  }
  if (line_bytes > size_t(std::numeric_limits<int32_t>::max())) return false;
  // Values are copied as they lie in memory, which is the file's little-endian order only on such a machine.
  static_assert(std::endian::native == std::endian::little);
  const auto put32 = [&](int32_t v) {
    char b[4];
    for (int i = 0; i < 4; ++i) b[i] = char(uint32_t(v) >> (8 * i));
    os.write(b, 4);
  };
  put32(Imf::MAGIC);
  // The long-names flag: some attribute, type or channel name has 32 characters or more (as OpenEXR decides it).
  bool long_names = false;
  for (auto a = header.begin(); a != header.end(); ++a)
    long_names |= std::strlen(a.name()) >= 32 || std::strlen(a.attribute().typeName()) >= 32;
  for (auto c = header.channels().begin(); c != header.channels().end(); ++c) long_names |= std::strlen(c.name()) >= 32;
  put32(Imf::EXR_VERSION | (long_names ? Imf::LONG_NAMES_FLAG : 0));
  header.writeTo(os);
  // The line offset table, then each line: its y, its size, and its values channel by channel.
  const int64_t lines = int64_t(dw.max.y) - dw.min.y + 1;
  uint64_t at = os.tellp() + uint64_t(lines) * 8;
  std::vector<char> table(size_t(lines) * 8);
  for (int64_t i = 0; i < lines; ++i, at += 8 + line_bytes)
    for (int b = 0; b < 8; ++b) table[size_t(i) * 8 + size_t(b)] = char(at >> (8 * b));
  os.write(table.data(), int(table.size()));
  std::vector<char> line(line_bytes);
  for (int64_t y = dw.min.y; y <= dw.max.y; ++y) {
    char* out = line.data();
    for (const Plane& p : planes) {
      const char* row = p.base + ptrdiff_t(y) * ptrdiff_t(p.y_stride) + ptrdiff_t(dw.min.x) * ptrdiff_t(p.x_stride);
      if (p.x_stride == p.bytes) {
        std::memcpy(out, row, width * p.bytes);
        out += width * p.bytes;
      } else if (p.bytes == 4) {  // constant sizes, so each copy is one move rather than a call to memcpy
        for (size_t x = 0; x < width; ++x, out += 4) std::memcpy(out, row + x * p.x_stride, 4);
      } else {
        for (size_t x = 0; x < width; ++x, out += 2) std::memcpy(out, row + x * p.x_stride, 2);
      }
    }
    put32(int32_t(y));
    put32(int32_t(line_bytes));
    os.write(line.data(), int(line_bytes));
  }
  return true;
}

}  // namespace tessera
