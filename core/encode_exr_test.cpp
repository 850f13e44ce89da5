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

}  // namespace
}  // namespace tessera
