#include "core/image/image.h"

#include "core/image/exr_layout.h"
#include "core/image/exr_uncompressed.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfThreading.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <fstream>
#include <iterator>
#include <unistd.h>

namespace tessera {
namespace {

TEST(EncodeExr, GivesTheBytesWriteExrWrites) {
  Image img = Image::make(5, 3);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) * 0.25f;
  ExrWriteOptions o;
  o.data_window = {10, 20, 15, 23};
  o.display_window = {0, 0, 40, 30};
  o.metadata = {{"tessera:spp", "4"}};
  const std::vector<uint8_t> bytes = encode_exr(img, o);
  const auto path = std::filesystem::temp_directory_path() / ("encode_exr_test_" + std::to_string(::getpid()) + ".exr");
  write_exr(path, img, o);
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bytes, file);
  const ExrImage back = read_exr(path);
  std::filesystem::remove(path);
  EXPECT_EQ(back.data_window, o.data_window);
  EXPECT_EQ(back.display_window, o.display_window);
  EXPECT_EQ(back.pixels.rgb, img.rgb);
  EXPECT_THROW(encode_exr(Image::make(0, 0)), ImageError);
}

// The direct writer of uncompressed files gives OpenEXR's own bytes: colours in float and half, extra float and uint
// channels, metadata, windows away from the origin, names that need the long-names flag, with and without threads in
// OpenEXR's pool; it declines compressed headers.
TEST(EncodeExr, UncompressedFilesAreOpenExrsBytesWrittenDirectly) {
  struct Case {
    int width, height;
    bool half, extra;
    std::string long_name;
  };
  const std::vector<Case> cases = {{64, 64, false, false, ""}, {1, 1, false, false, ""}, {37, 5, true, true, ""},
                                   {13, 17, false, true, std::string(40, 'n')}, {200, 3, true, false, ""}};
  const int pool = Imf::globalThreadCount();  // restored at the end
  for (const int threads : {0, 2}) {
    Imf::setGlobalThreadCount(threads);
    for (const Case& c : cases) {
      Image img = Image::make(c.width, c.height);
      uint32_t x = 7;
      for (float& v : img.rgb) v = float((x = x * 1664525u + 1013904223u) >> 8) * 0x1p-20f;
      if (c.extra) {
        img.extra["variance.R"].assign(size_t(c.width) * size_t(c.height), 0.5f);
        img.uint_extra["samples"].assign(size_t(c.width) * size_t(c.height), 16u);
        if (!c.long_name.empty()) img.extra[c.long_name].assign(size_t(c.width) * size_t(c.height), -1.f);
      }
      ExrWriteOptions o;
      o.compression = ExrCompression::kNone;
      o.half = c.half;
      o.write_extra = c.extra;
      o.data_window = {3, 9, 3 + c.width, 9 + c.height};
      o.display_window = {0, 0, 300, 300};
      o.metadata = {{"tessera:spp", "16"}};
      if (!c.long_name.empty()) o.metadata[c.long_name + ":key"] = "v";
      const PixelWindow data = exr_layout::data_window(img, o);
      const Imf::Header header = exr_layout::header(img, o, data);
      const exr_layout::Frame frame = exr_layout::frame(img, o, data);
      exr_io::MemoryOStream theirs("theirs"), ours("ours");
      {
        Imf::OutputFile out(theirs, header, 0);
        out.setFrameBuffer(frame.buffer);
        out.writePixels(c.height);
      }
      ASSERT_TRUE(write_uncompressed_exr(ours, header, frame.buffer));
      EXPECT_EQ(ours.bytes(), theirs.bytes()) << c.width << "x" << c.height << " half " << c.half << " extra " << c.extra
                                              << " long name " << !c.long_name.empty() << ", " << threads << " threads";
      EXPECT_EQ(encode_exr(img, o), theirs.bytes());
    }
  }
  Imf::setGlobalThreadCount(pool);
  const Image img = Image::make(4, 4);
  const ExrWriteOptions zip;  // ZIP by default
  const PixelWindow data = exr_layout::data_window(img, zip);
  exr_io::MemoryOStream out("zip");
  EXPECT_FALSE(write_uncompressed_exr(out, exr_layout::header(img, zip, data), exr_layout::frame(img, zip, data).buffer));
  EXPECT_TRUE(out.bytes().empty());
  // A channel without a slice (OutputFile would write zeros for it) is left to OutputFile too.
  ExrWriteOptions plain;
  plain.compression = ExrCompression::kNone;
  Imf::Header more = exr_layout::header(img, plain, data);
  more.channels().insert("Z", Imf::Channel(Imf::FLOAT));
  EXPECT_FALSE(write_uncompressed_exr(out, more, exr_layout::frame(img, plain, data).buffer));
  EXPECT_TRUE(out.bytes().empty());
}

// decode_exr reads from memory what read_exr reads from a file, and refuses short, foreign and cut-off bytes in words.
TEST(EncodeExr, CompressedBytesDoNotDependOnTheThreadCount) {
  // Many line blocks, noisy values: each block is compressed on OpenEXR's pool, as many threads as the render may use.
  Image img = Image::make(97, 211);
  uint32_t x = 12345;
  for (float& v : img.rgb) {
    x = x * 1664525u + 1013904223u;
    v = float(x >> 8) * 0x1p-24f;
  }
  for (const ExrCompression c : {ExrCompression::kZip, ExrCompression::kPiz}) {
    ExrWriteOptions o;
    o.compression = c;
    std::vector<std::vector<uint8_t>> encoded;
    for (const size_t threads : {size_t(1), size_t(2), size_t(7)}) {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      encoded.push_back(encode_exr(img, o));
    }
    EXPECT_EQ(encoded[0], encoded[1]);
    EXPECT_EQ(encoded[0], encoded[2]);
    EXPECT_EQ(decode_exr(std::string_view(reinterpret_cast<const char*>(encoded[2].data()), encoded[2].size())).pixels.rgb,
              img.rgb);
  }
}

TEST(DecodeExr, ReadsTheBytesEncodeExrGivesAndRefusesBrokenOnes) {
  Image img = Image::make(4, 3);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) * 0.5f - 1.f;
  img.uint_extra["tessera.samples"] = std::vector<uint32_t>(12, 0xdeadbeefu);
  ExrWriteOptions o;
  o.data_window = {3, 2, 7, 5};
  o.display_window = {0, 0, 9, 9};
  o.metadata = {{"tessera:seed", "5"}};
  const std::vector<uint8_t> bytes = encode_exr(img, o);
  const std::string data(bytes.begin(), bytes.end());
  const ExrImage back = decode_exr(data);
  EXPECT_EQ(back.data_window, o.data_window);
  EXPECT_EQ(back.display_window, o.display_window);
  EXPECT_EQ(back.pixels.rgb, img.rgb);
  EXPECT_EQ(back.pixels.uint_extra, img.uint_extra);
  EXPECT_EQ(back.metadata.at("tessera:seed"), "5");
  const auto error = [](std::string_view b) {
    try {
      decode_exr(b);
    } catch (const ImageError& e) {
      return std::string(e.what());
    }
    return std::string("(read)");
  };
  EXPECT_NE(error("").find("no magic number"), std::string::npos);
  EXPECT_NE(error("not an exr at all").find("no magic number"), std::string::npos);
  EXPECT_NE(error(std::string_view(data).substr(0, 6)).find("ends inside the version field"), std::string::npos);
  EXPECT_EQ(error(std::string_view(data).substr(0, data.size() / 2)).rfind("cannot read EXR data", 0), 0u);
}

}  // namespace
}  // namespace tessera
