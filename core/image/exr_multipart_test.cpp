// Multi-part EXRs: parts written as asked (the colour and the channels of no part first), read back as one image with
// every channel's bits, and refusals for channels the image lacks or names twice.
#include "core/image/exr_multipart.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include <unistd.h>

namespace tessera {
namespace {

TEST(ExrMultipart, PartsRoundTripToOneImage) {
  Image img = Image::make(5, 3);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) + 0.5f;
  for (const char* c : {"albedo.R", "albedo.G", "albedo.B", "Z", "samples"}) img.extra[c].assign(15, float(std::strlen(c)));
  img.extra["Z"][4] = -1.f / 0.f;
  ExrWriteOptions o;
  o.display_window = PixelWindow{0, 0, 10, 10};
  o.data_window = PixelWindow{2, 3, 7, 6};
  o.metadata = {{"cryptomatte/abc1234/name", "x"}};
  const auto path = std::filesystem::temp_directory_path() / ("tessera-multipart-" + std::to_string(::getpid()) + ".exr");
  write_exr_multipart(path, img, o, {{"albedo", {"albedo.R", "albedo.G", "albedo.B"}}, {"depth", {"Z"}}});
  const ExrImage first = read_exr(path);  // the first part alone: colour and the channels of no part
  EXPECT_EQ(first.pixels.extra.size(), 1u);
  EXPECT_TRUE(first.pixels.extra.count("samples"));
  const ExrImage all = read_exr_all_parts(path);
  EXPECT_EQ(all.data_window, o.data_window);
  EXPECT_EQ(all.metadata.at("cryptomatte/abc1234/name"), "x");
  EXPECT_EQ(all.pixels.rgb, img.rgb);
  ASSERT_EQ(all.pixels.extra.size(), img.extra.size());
  for (const auto& [name, values] : img.extra)
    EXPECT_EQ(std::memcmp(all.pixels.extra.at(name).data(), values.data(), values.size() * 4), 0) << name;
  EXPECT_THROW(write_exr_multipart(path, img, o, {{"n", {"N.X"}}}), ImageError);
  EXPECT_THROW(write_exr_multipart(path, img, o, {{"a", {"Z"}}, {"b", {"Z"}}}), ImageError);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace tessera
