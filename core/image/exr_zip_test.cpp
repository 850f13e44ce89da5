#include "core/image/exr_zip.h"

#include "core/image/exr_layout.h"
#include "core/image/image.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {
namespace {

// Every channel's values of an EXR in memory, read by OpenEXR's C++ library (its own zlib decoder), with the header.
struct Decoded {
  std::map<std::string, std::vector<char>> channels;
  Imf::Header header;
};

Decoded read_with_openexr(const std::vector<uint8_t>& bytes) {
  exr_io::MemoryIStream stream(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), "file");
  Imf::InputFile in(stream, 0);
  Decoded out;
  out.header = in.header();
  const Imath::Box2i dw = in.header().dataWindow();
  const size_t w = size_t(dw.max.x - dw.min.x + 1), h = size_t(dw.max.y - dw.min.y + 1);
  Imf::FrameBuffer fb;
  for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) {
    const size_t bytes_per = c.channel().type == Imf::HALF ? 2 : 4;
    std::vector<char>& v = out.channels[c.name()];
    v.assign(w * h * bytes_per, 0);
    fb.insert(c.name(), Imf::Slice(c.channel().type, v.data() - (ptrdiff_t(dw.min.x) + ptrdiff_t(dw.min.y) * ptrdiff_t(w)) * ptrdiff_t(bytes_per),
                                   bytes_per, bytes_per * w));
  }
  in.setFrameBuffer(fb);
  in.readPixels(dw.min.y, dw.max.y);
  return out;
}

Image noisy_or_flat(int width, int height, bool noisy, bool extra) {
  Image img = Image::make(width, height);
  uint32_t x = 99;
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = noisy ? float((x = x * 1664525u + 1013904223u) >> 8) * 0x1p-20f : 0.25f;
  if (extra) {
    img.extra["variance.R"].assign(size_t(width) * size_t(height), 0.5f);
    img.uint_extra["samples"].assign(size_t(width) * size_t(height), 16u);
  }
  return img;
}

// The files written directly are the files OpenEXR writes, but for the compressed bytes: OpenEXR's own reader gets
// every channel back bit for bit and the same header, for ZIP and ZIPS, float and half colours, extra float and uint
// channels, windows away from the origin, a last chunk of fewer lines, compressible and incompressible chunks; the
// bytes do not depend on the threads.
TEST(ExrZip, OpenExrReadsBackEveryBitWrittenDirectly) {
  struct Case {
    int width, height;
    bool half, extra, noisy;
  };
  const std::vector<Case> cases = {{64, 64, false, false, true}, {1, 1, false, false, true}, {37, 5, true, true, true},
                                   {13, 17, false, true, false},  {200, 3, true, false, false}, {97, 211, false, true, true}};
  for (const Imf::Compression compression : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION}) {
    for (const Case& c : cases) {
      const Image img = noisy_or_flat(c.width, c.height, c.noisy, c.extra);
      ExrWriteOptions o;
      o.half = c.half;
      o.write_extra = c.extra;
      o.data_window = {-3, 9, -3 + c.width, 9 + c.height};
      o.display_window = {0, 0, 300, 300};
      o.metadata = {{"tessera:spp", "16"}};
      const PixelWindow data = exr_layout::data_window(img, o);
      Imf::Header header = exr_layout::header(img, o, data);
      header.compression() = compression;
      const exr_layout::Frame frame = exr_layout::frame(img, o, data);
      exr_io::MemoryOStream theirs("theirs"), ours("ours"), ours_threaded("ours, threads");
      {
        Imf::OutputFile out(theirs, header, 0);
        out.setFrameBuffer(frame.buffer);
        out.writePixels(c.height);
      }
      ASSERT_TRUE(write_zip_exr(ours, header, frame.buffer, 1));
      ASSERT_TRUE(write_zip_exr(ours_threaded, header, frame.buffer, 4));
      const std::string what = std::to_string(c.width) + "x" + std::to_string(c.height) + " half " +
                               std::to_string(c.half) + " extra " + std::to_string(c.extra) + " noisy " +
                               std::to_string(c.noisy) + " compression " + std::to_string(int(compression));
      EXPECT_EQ(ours.bytes(), ours_threaded.bytes()) << what;
      const Decoded a = read_with_openexr(ours.bytes()), b = read_with_openexr(theirs.bytes());
      EXPECT_EQ(a.channels, b.channels) << what;
      EXPECT_EQ(a.header.compression(), compression) << what;
      EXPECT_EQ(a.header.dataWindow(), b.header.dataWindow()) << what;
      EXPECT_TRUE(a.header.channels() == b.header.channels()) << what;
      // Incompressible chunks are stored raw, as OpenEXR stores them: the two files are then the same size.
      if (c.noisy && !c.half && !c.extra) {
        EXPECT_EQ(ours.bytes().size(), theirs.bytes().size()) << what;
      }
      if (!c.noisy) {
        EXPECT_LT(ours.bytes().size(), theirs.bytes().size() * 11 / 10 + 64) << what;  // a few bytes more per chunk at most
      }
    }
  }
}

// Other compressions are left to OpenEXR, having written nothing.
TEST(ExrZip, DeclinesOtherCompressions) {
  const Image img = noisy_or_flat(4, 4, true, false);
  ExrWriteOptions o;
  const PixelWindow data = exr_layout::data_window(img, o);
  for (const Imf::Compression c : {Imf::NO_COMPRESSION, Imf::PIZ_COMPRESSION, Imf::RLE_COMPRESSION}) {
    Imf::Header header = exr_layout::header(img, o, data);
    header.compression() = c;
    exr_io::MemoryOStream out("other");
    EXPECT_FALSE(write_zip_exr(out, header, exr_layout::frame(img, o, data).buffer, 1));
    EXPECT_TRUE(out.bytes().empty());
  }
  EXPECT_EQ(zip_lines_per_chunk(Imf::ZIP_COMPRESSION), 16);
  EXPECT_EQ(zip_lines_per_chunk(Imf::ZIPS_COMPRESSION), 1);
  EXPECT_EQ(zip_lines_per_chunk(Imf::PIZ_COMPRESSION), 0);
}

// A chunk's data: the raw bytes when deflating does not make them smaller, otherwise a zlib stream (its first byte
// 0x78: deflate with a 32 KiB window) shorter than they are.
TEST(ExrZip, ChunksAreDeflatedOnlyWhenThatIsSmaller) {
  ZipChunkCompressor z(1);
  const std::vector<char> flat(4096, 7);
  const std::vector<char> packed = z.compress(flat.data(), flat.size());
  ASSERT_LT(packed.size(), flat.size());
  EXPECT_EQ(uint8_t(packed[0]), 0x78);
  std::vector<char> noise(4096);
  uint32_t x = 1;
  for (char& c : noise) c = char((x = x * 1664525u + 1013904223u) >> 24);
  EXPECT_EQ(z.compress(noise.data(), noise.size()), noise);
  EXPECT_EQ(z.compress(noise.data(), 1), std::vector<char>(noise.begin(), noise.begin() + 1));
}

}  // namespace
}  // namespace tessera
