#include "core/image.h"

#include <gtest/gtest.h>

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
