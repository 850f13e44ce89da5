#include "server/assembly.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <sys/resource.h>

namespace tessera::server {
namespace {

// A tile of random bits (finite floats) in the window [x0, x1) x [y0, y1) of a width x height image, as workers
// encode it (uncompressed unless told otherwise).
std::string tile_exr(const PixelWindow& w, int width, int height, ExrCompression compression = ExrCompression::kNone,
                     Image* pixels = nullptr) {
  Image img = Image::make(w.width(), w.height());
  std::mt19937 rng(7);
  for (float& v : img.rgb) {
    do {
      const uint32_t bits = rng();
      std::memcpy(&v, &bits, sizeof v);
    } while (!std::isfinite(v));
  }
  ExrWriteOptions o;
  o.compression = compression;
  o.data_window = w;
  o.display_window = PixelWindow{0, 0, width, height};
  const std::vector<uint8_t> bytes = encode_exr(img, o);
  if (pixels) *pixels = img;
  return std::string(bytes.begin(), bytes.end());
}

TEST(CheckTileExr, TheWorkersLayoutDecodesToTheSameBitsAsOpenExr) {
  for (const PixelWindow w : {PixelWindow{64, 32, 128, 96}, PixelWindow{0, 0, 1, 1}, PixelWindow{90, 7, 100, 10}}) {
    Image sent;
    const std::string exr = tile_exr(w, 100, 96, ExrCompression::kNone, &sent);
    const TileCheck c = check_tile_exr(exr, w, 100, 96);
    ASSERT_FALSE(c.error) << *c.error;
    const ExrImage reference = decode_exr(exr);
    ASSERT_EQ(c.pixels.rgb.size(), reference.pixels.rgb.size());
    EXPECT_EQ(std::memcmp(c.pixels.rgb.data(), reference.pixels.rgb.data(), c.pixels.rgb.size() * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(c.pixels.rgb.data(), sent.rgb.data(), sent.rgb.size() * sizeof(float)), 0);
  }
}

TEST(CheckTileExr, OtherLayoutsGoThroughOpenExr) {
  const PixelWindow w{16, 16, 32, 32};
  Image sent;
  const std::string zip = tile_exr(w, 64, 64, ExrCompression::kZip, &sent);
  const TileCheck c = check_tile_exr(zip, w, 64, 64);
  ASSERT_FALSE(c.error) << *c.error;
  EXPECT_EQ(std::memcmp(c.pixels.rgb.data(), sent.rgb.data(), sent.rgb.size() * sizeof(float)), 0);
}

TEST(CheckTileExr, RefusalsNameTheProblem) {
  const PixelWindow w{0, 0, 8, 8};
  std::string exr = tile_exr(w, 16, 16);
  EXPECT_NE(check_tile_exr(exr, PixelWindow{8, 0, 16, 8}, 16, 16).error.value_or("").find("data window is [0, 0, 8, 8)"),
            std::string::npos);
  EXPECT_NE(check_tile_exr(exr, w, 32, 16).error.value_or("").find("display window"), std::string::npos);
  EXPECT_NE(check_tile_exr(exr.substr(0, exr.size() - 10), w, 16, 16).error.value_or("").find("not a readable"),
            std::string::npos);
  EXPECT_NE(check_tile_exr("not an exr", w, 16, 16).error.value_or("").find("not a readable"), std::string::npos);
  // A NaN in the last pixel (R of the last line is the last plane written): found wherever it is.
  Image img = Image::make(8, 8);
  img.rgb.back() = std::numeric_limits<float>::quiet_NaN();
  ExrWriteOptions o;
  o.compression = ExrCompression::kNone;
  o.data_window = w;
  o.display_window = PixelWindow{0, 0, 16, 16};
  const std::vector<uint8_t> nan = encode_exr(img, o);
  EXPECT_EQ(check_tile_exr(std::string(nan.begin(), nan.end()), w, 16, 16).error.value_or(""),
            "pixel (7, 7) is not finite");
  // Half colours are decodable but refused.
  o.half = true;
  const std::vector<uint8_t> half = encode_exr(Image::make(8, 8), o);
  EXPECT_EQ(check_tile_exr(std::string(half.begin(), half.end()), w, 16, 16).error.value_or(""),
            "channel R is not float32");
}

// A tile's header that claims a huge image (its data window rewritten in place to 8192x8192, the file still a few
// hundred bytes of ZIP data) is refused from the header, before a decoder allocates the claim.
TEST(CheckTileExr, AHeaderClaimingMoreThanTheTileIsRefusedBeforeDecoding) {
  const PixelWindow w{0, 0, 16, 16};
  std::string exr = tile_exr(w, 8192, 8192, ExrCompression::kZip);
  const std::string key("dataWindow\0box2i\0", 17);
  const size_t at = exr.find(key);
  ASSERT_NE(at, std::string::npos);
  const int32_t claim[4] = {0, 0, 8191, 8191};  // xMin, yMin, xMax, yMax (inclusive), little-endian
  std::memcpy(exr.data() + at + key.size() + 4, claim, sizeof claim);
  rusage before{};
  ::getrusage(RUSAGE_SELF, &before);
  EXPECT_EQ(check_tile_exr(exr, w, 8192, 8192).error.value_or(""),
            "data window is [0, 0, 8192, 8192), expected the tile's [0, 0, 16, 16)");
  rusage after{};
  ::getrusage(RUSAGE_SELF, &after);
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "peak memory grew by more than 64 MiB (in KiB)";
  // Multi-part and deep files are not tiles.
  std::string parts = tile_exr(w, 16, 16);
  parts[5] = char(parts[5] | 0x10);  // the multi-part flag (0x1000 of the version field)
  EXPECT_EQ(check_tile_exr(parts, w, 16, 16).error.value_or(""), "a tile must be one flat image, not deep or multi-part");
}

// The width and height a PNG's header gives.
std::pair<uint32_t, uint32_t> png_size(const std::vector<uint8_t>& png) {
  const auto be32 = [&](size_t at) {
    return uint32_t(png.at(at)) << 24 | uint32_t(png.at(at + 1)) << 16 | uint32_t(png.at(at + 2)) << 8 | png.at(at + 3);
  };
  return {be32(16), be32(20)};
}

// A preview is at most kMaxPreviewSide on its long side, a whole-factor box filter of the frame; a job none of whose
// tiles arrived costs only the preview's pixels, not the frame's.
TEST(JobImage, PreviewsAreBoundedAndAQueuedJobAllocatesNoFrame) {
  rusage before{};
  ::getrusage(RUSAGE_SELF, &before);
  JobImage queued(8192, 8192);
  EXPECT_EQ(png_size(queued.preview_png()), std::make_pair(1024u, 1024u));
  EXPECT_EQ(png_size(preview_png(nullptr, 3000, 2000)), std::make_pair(1000u, 667u));  // factor 3, edge blocks partial
  rusage after{};
  ::getrusage(RUSAGE_SELF, &after);
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "peak memory grew by more than 64 MiB (in KiB)";
  // Small frames keep their size; a frame just over the bound is scaled by 3 and its blocks averaged: the first
  // pixel of a 2050 x 1 frame whose first three pixels are 1, 1, 0.25 is their mean, 0.75, and the last block holds
  // the frame's last pixel alone.
  EXPECT_EQ(png_size(JobImage(640, 480).preview_png()), std::make_pair(640u, 480u));
  Image frame = Image::make(2050, 1);
  frame.set(0, 0, Vec3(1.f));
  frame.set(1, 0, Vec3(1.f));
  frame.set(2, 0, Vec3(0.25f));
  const std::vector<uint8_t> png = preview_png(&frame, 2050, 1);
  EXPECT_EQ(png_size(png), std::make_pair(684u, 1u));
  frame.set(2049, 0, Vec3(0.5f));
  const Image small = preview_image(&frame, 2050, 1);
  EXPECT_EQ(small.at(0, 0), Vec3(0.75f));
  EXPECT_EQ(small.at(683, 0), Vec3(0.5f));
}

}  // namespace
}  // namespace tessera::server

namespace tessera::server {
namespace {

// A layered tile (its colour and two layer channels) as a worker uploads it.
Image layered_tile(const PixelWindow& w) {
  Image img = Image::make(w.width(), w.height());
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) * 0.25f;
  const size_t n = size_t(w.width()) * size_t(w.height());
  img.extra["Z"].assign(n, std::numeric_limits<float>::infinity());  // depth may be infinite: only colours are checked
  img.extra["object_id"].assign(n, 3.f);
  img.extra["tessera.unused"].assign(n, 1.f);  // not a layer of the job: dropped
  return img;
}

TEST(CheckTileExr, LayeredTilesKeepTheirLayersAndStoreThemAfterTheColour) {
  const PixelWindow w{8, 4, 24, 12};
  const Image sent = layered_tile(w);
  ExrWriteOptions o;
  o.compression = ExrCompression::kNone;
  o.data_window = w;
  o.display_window = PixelWindow{0, 0, 32, 16};
  const std::vector<uint8_t> bytes = encode_exr(sent, o);
  const std::string exr(bytes.begin(), bytes.end());
  const std::vector<std::string> layers = {"Z", "object_id"};
  const TileCheck c = check_tile_exr(exr, w, 32, 16, layers);
  ASSERT_FALSE(c.error) << *c.error;
  EXPECT_EQ(c.pixels.extra.size(), 2u);
  EXPECT_EQ(c.pixels.extra.at("object_id"), sent.extra.at("object_id"));
  const TileCheck missing = check_tile_exr(exr, w, 32, 16, {"Z", "N.X"});
  ASSERT_TRUE(missing.error);
  EXPECT_EQ(*missing.error, "channel N.X is missing");
  std::string buffer;
  const std::string_view stored = tile_bytes(c.pixels, layers, buffer);
  EXPECT_EQ(stored.size(), size_t(w.width() * w.height()) * 5 * sizeof(float));
  const Image back = tile_from_bytes(stored, w.width(), w.height(), layers);
  EXPECT_EQ(back.rgb, sent.rgb);
  EXPECT_EQ(std::memcmp(back.extra.at("Z").data(), sent.extra.at("Z").data(), sent.extra.at("Z").size() * 4), 0);
  EXPECT_THROW(tile_from_bytes(stored, w.width(), w.height()), std::invalid_argument);
  // A job's image takes the layers of its tiles and writes them beside the colour.
  JobImage job(32, 16, layers);
  job.paste(c.pixels, w);
  EXPECT_FALSE(job.layer_preview_png(Layer::kObjectId).empty());
  EXPECT_THROW(job.layer_preview_png(Layer::kAlbedo), std::invalid_argument);
}

}  // namespace
}  // namespace tessera::server
