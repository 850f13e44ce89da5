#include "core/image.h"

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
