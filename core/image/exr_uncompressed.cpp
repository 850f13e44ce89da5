#include "core/image/exr_uncompressed.h"

#include "core/image/exr_scanline.h"

#include <cstdint>
#include <vector>

namespace tessera {

bool write_uncompressed_exr(Imf::OStream& os, const Imf::Header& header, const Imf::FrameBuffer& frame) {
  if (header.compression() != Imf::NO_COMPRESSION) return false;
  const std::optional<exr_scanline::Lines> lines = exr_scanline::Lines::of(header, frame);
  if (!lines) return false;
  exr_scanline::write_start(os, header);
  // The line offset table, then each line: its y, its size, and its values channel by channel. Every line has the
  // same size, so the lines are packed one at a time as they are written.
  const Imath::Box2i dw = header.dataWindow();
  const int64_t count = int64_t(dw.max.y) - dw.min.y + 1;
  const size_t line_bytes = lines->line_bytes();
  exr_scanline::write_offset_table(os, std::vector<size_t>(size_t(count), line_bytes));
  std::vector<char> line(8 + line_bytes);
  for (int64_t y = dw.min.y; y <= dw.max.y; ++y) {
    for (int i = 0; i < 4; ++i) {
      line[size_t(i)] = char(uint32_t(int32_t(y)) >> (8 * i));
      line[size_t(4 + i)] = char(uint32_t(line_bytes) >> (8 * i));
    }
    lines->pack(y, line.data() + 8);
    os.write(line.data(), int(line.size()));
  }
  return true;
}

}  // namespace tessera
