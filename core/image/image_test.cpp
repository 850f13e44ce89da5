// Image I/O tests: EXR round trips (float, half, windows, extra channels, metadata), files written by other OpenEXR
// writers (Y-only, tiled, luminance/chroma), rejection of bad files, sRGB PNG encoding and atomic writes.
#include "core/image/image.h"

#include "core/image/exr_layout.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfPreviewImage.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

namespace tessera {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test (tests may run in parallel under ctest), removed afterwards.
class ImageFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) /
           ("tessera_image_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path file(const std::string& name) const { return dir_ / name; }

  fs::path dir_;
};

class ImageExr : public ImageFileTest {};
class ImagePng : public ImageFileTest {};
class ImageAtomic : public ImageFileTest {};

// An image with a smooth ramp plus noise, so that compression cannot make it trivially small.
Image test_image(int w, int h, uint32_t seed = 1) {
  Image img = Image::make(w, h);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(0.f, 0.25f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.set(x, y, Vec3(float(x) / float(w), float(y) / float(h), 0.5f) + Vec3(noise(rng), noise(rng), noise(rng)));
  return img;
}

std::vector<uint8_t> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::vector<uint8_t>& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

// Runs f, which must throw ImageError, and returns the error's message.
template <class F>
std::string image_error_message(F&& f) {
  try {
    f();
  } catch (const ImageError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw a non-ImageError: " << e.what();
    return {};
  }
  ADD_FAILURE() << "did not throw";
  return {};
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(ImageBasics, PixelWindowGeometry) {
  const PixelWindow w{-2, 3, 8, 7};
  EXPECT_EQ(w.width(), 10);
  EXPECT_EQ(w.height(), 4);
  EXPECT_FALSE(w.empty());
  EXPECT_TRUE(w.contains(w));
  EXPECT_TRUE(w.contains({0, 3, 8, 4}));
  EXPECT_FALSE(w.contains({0, 2, 8, 4}));
  EXPECT_FALSE(w.contains({0, 3, 9, 4}));
  EXPECT_TRUE(w.contains({100, 100, 100, 200}));  // empty
  EXPECT_TRUE(PixelWindow{}.empty());
  EXPECT_TRUE((PixelWindow{5, 0, 2, 3}.empty()));
  EXPECT_EQ((PixelWindow{5, 0, 2, 3}.width()), 0);
}

TEST(ImageBasics, MakeAtSet) {
  Image img = Image::make(3, 2);
  EXPECT_EQ(img.rgb.size(), 18u);
  EXPECT_TRUE(std::all_of(img.rgb.begin(), img.rgb.end(), [](float v) { return v == 0.f; }));
  img.set(2, 1, {1.f, 2.f, 3.f});
  EXPECT_EQ(img.at(2, 1), Vec3(1.f, 2.f, 3.f));
  EXPECT_EQ(img.rgb[3 * (1 * 3 + 2) + 1], 2.f);  // row-major, interleaved
  EXPECT_THROW(Image::make(-1, 2), ImageError);
}

TEST_F(ImageExr, FloatRoundTripIsBitwiseIdentical) {
  Image img = Image::make(37, 23);
  std::mt19937 rng(7);
  for (float& v : img.rgb) v = std::bit_cast<float>(uint32_t(rng()));  // every bit pattern: NaNs, infs, denormals
  img.rgb[0] = -0.f;
  img.rgb[1] = std::numeric_limits<float>::infinity();
  img.rgb[2] = std::numeric_limits<float>::denorm_min();
  const fs::path p = file("float.exr");
  write_exr(p, img);
  const ExrImage back = read_exr(p);
  EXPECT_EQ(back.pixels.width, 37);
  EXPECT_EQ(back.pixels.height, 23);
  EXPECT_TRUE(same_bits(back.pixels.rgb, img.rgb));
  EXPECT_EQ(back.data_window, (PixelWindow{0, 0, 37, 23}));
  EXPECT_EQ(back.display_window, (PixelWindow{0, 0, 37, 23}));
  EXPECT_TRUE(back.pixels.extra.empty());
  EXPECT_TRUE(back.metadata.empty());
}

TEST_F(ImageExr, EveryCompressionRoundTripsBitwiseAndIsRecordedInTheHeader) {
  Image img = Image::make(61, 35);  // not a multiple of ZIP's 16 or PIZ's 32 scanlines
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = 0.5f + 0.25f * std::sin(float(i) * 0.01f) + 1e-3f * u(rng);
  const std::pair<ExrCompression, Imf::Compression> modes[] = {{ExrCompression::kZip, Imf::ZIP_COMPRESSION},
                                                               {ExrCompression::kPiz, Imf::PIZ_COMPRESSION},
                                                               {ExrCompression::kNone, Imf::NO_COMPRESSION}};
  for (const auto& [mode, imf] : modes) {
    const fs::path p = file("compression.exr");
    write_exr(p, img, {.compression = mode});
    {
      Imf::InputFile in(p.c_str());
      EXPECT_EQ(in.header().compression(), imf);
    }
    EXPECT_EQ(read_exr(p).pixels.rgb, img.rgb) << int(imf);
  }
}

// ZIP files of 32-bit values are written at zlib's level 1 (rendered floats compress about as well at any level),
// half colours at OpenEXR's default level, under which they compress better.
TEST(ExrLayout, ZipLevelIsOneForFloatsAndTheDefaultForHalfColours) {
  const Image img = Image::make(8, 4);
  const PixelWindow data{0, 0, 8, 4};
  EXPECT_EQ(exr_layout::header(img, {}, data).zipCompressionLevel(), 1);
  EXPECT_EQ(exr_layout::header(img, {.half = true}, data).zipCompressionLevel(), Imf::Header(8, 4).zipCompressionLevel());
}

TEST_F(ImageExr, HalfRoundTripWithinHalfPrecision) {
  Image img = Image::make(16, 9);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> mag(-12.f, 12.f);
  for (float& v : img.rgb) v = (rng() & 1 ? 1.f : -1.f) * std::exp2(mag(rng));
  img.rgb[0] = 0.5f;
  img.rgb[1] = 1e-6f;  // a half denormal
  img.extra["samples"] = std::vector<float>(16 * 9, 4097.f);  // not representable in half
  const fs::path p = file("half.exr");
  write_exr(p, img, {.half = true});
  {
    Imf::InputFile in(p.c_str());
    EXPECT_EQ(in.header().channels().findChannel("R")->type, Imf::HALF);
    EXPECT_EQ(in.header().channels().findChannel("samples")->type, Imf::FLOAT);
  }
  const ExrImage back = read_exr(p);
  ASSERT_EQ(back.pixels.rgb.size(), img.rgb.size());
  for (size_t i = 0; i < img.rgb.size(); ++i) {
    const float v = img.rgb[i];
    EXPECT_NEAR(back.pixels.rgb[i], v, std::max(std::abs(v) * 0x1p-11f, 0x1p-25f)) << i;
  }
  EXPECT_EQ(back.pixels.rgb[0], 0.5f);
  EXPECT_EQ(back.pixels.extra.at("samples"), img.extra.at("samples"));  // extra channels stay float
}

TEST_F(ImageExr, DataWindowInsideLargerDisplayWindowRoundTrips) {
  const Image img = test_image(20, 10);
  const fs::path p = file("crop.exr");
  ExrWriteOptions opt;
  opt.display_window = {0, 0, 64, 48};
  opt.data_window = {30, 17, 50, 27};
  write_exr(p, img, opt);
  const ExrImage back = read_exr(p);
  EXPECT_EQ(back.display_window, opt.display_window);
  EXPECT_EQ(back.data_window, opt.data_window);
  EXPECT_TRUE(same_bits(back.pixels.rgb, img.rgb));

  // A data window reaching outside the display window, at negative coordinates (overscan).
  opt.data_window = {-5, -3, 15, 7};
  write_exr(p, img, opt);
  const ExrImage overscan = read_exr(p);
  EXPECT_EQ(overscan.display_window, opt.display_window);
  EXPECT_EQ(overscan.data_window, opt.data_window);
  EXPECT_TRUE(same_bits(overscan.pixels.rgb, img.rgb));

  // Only the data window given: the display window defaults to it.
  write_exr(p, img, {.data_window = {100, 200, 120, 210}});
  const ExrImage no_display = read_exr(p);
  EXPECT_EQ(no_display.display_window, (PixelWindow{100, 200, 120, 210}));
  EXPECT_EQ(no_display.data_window, (PixelWindow{100, 200, 120, 210}));
}

TEST_F(ImageExr, ExtraChannelsRoundTrip) {
  Image img = test_image(12, 7);
  for (const char* name : {"variance.R", "variance.G", "variance.B", "samples", "A"}) {
    auto& ch = img.extra[name];
    ch.resize(12 * 7);
    for (size_t i = 0; i < ch.size(); ++i) ch[i] = float(i) * 0.37f + float(std::strlen(name));
  }
  const fs::path p = file("extra.exr");
  write_exr(p, img, {.data_window = {3, 4, 15, 11}});
  const ExrImage back = read_exr(p);
  EXPECT_TRUE(same_bits(back.pixels.rgb, img.rgb));
  ASSERT_EQ(back.pixels.extra.size(), img.extra.size());
  for (const auto& [name, values] : img.extra) {
    ASSERT_TRUE(back.pixels.extra.count(name)) << name;
    EXPECT_TRUE(same_bits(back.pixels.extra.at(name), values)) << name;
  }

  write_exr(p, img, {.write_extra = false});
  EXPECT_TRUE(read_exr(p).pixels.extra.empty());
}

TEST_F(ImageExr, HeaderReadsWindowsMetadataAndChannelTypesWithoutPixels) {
  Image img = test_image(64, 48);
  img.extra["variance.R"].assign(64 * 48, 0.5f);
  img.uint_extra["tessera.samples"].assign(64 * 48, 3u);
  const fs::path p = file("header.exr");
  write_exr(p, img, {.half = true, .display_window = {0, 0, 80, 50}, .data_window = {3, 2, 67, 50},
                     .metadata = {{"tessera:seed", "7"}}});
  const ExrHeader h = read_exr_header(p);
  EXPECT_EQ(h.data_window, (PixelWindow{3, 2, 67, 50}));
  EXPECT_EQ(h.display_window, (PixelWindow{0, 0, 80, 50}));
  EXPECT_EQ(h.metadata.at("tessera:seed"), "7");
  EXPECT_EQ(h.metadata, read_exr(p).metadata);
  const std::map<std::string, ExrPixelType> channels = {{"R", ExrPixelType::kHalf},
                                                        {"G", ExrPixelType::kHalf},
                                                        {"B", ExrPixelType::kHalf},
                                                        {"variance.R", ExrPixelType::kFloat},
                                                        {"tessera.samples", ExrPixelType::kUint}};
  EXPECT_EQ(h.channels, channels);
  // The pixels are not read: a file cut after its header still gives the header, and read_exr refuses it.
  const std::vector<uint8_t> bytes = read_bytes(p);
  const fs::path cut = file("cut.exr");
  write_bytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.end() - 100));
  EXPECT_EQ(read_exr_header(cut).metadata.at("tessera:seed"), "7");
  EXPECT_THROW(read_exr(cut), ImageError);
  // Not an EXR, or no file: an ImageError naming the path.
  std::ofstream(file("text.exr")) << "hello";
  for (const fs::path& bad : {file("text.exr"), file("missing.exr")}) {
    const std::string msg = image_error_message([&] { read_exr_header(bad); });
    EXPECT_NE(msg.find(bad.string()), std::string::npos) << msg;
  }
}

TEST_F(ImageExr, MetadataRoundTrips) {
  const std::map<std::string, std::string> metadata = {
      {"tessera/scene", "cbox.json"},
      {"tessera/spp", "1024"},
      {"empty", ""},
      {"a.name.longer.than.thirty.one.characters", "long names need the long-name flag"},
      {"comments", "line one\nline two, caf\xC3\xA9"},
  };
  const fs::path p = file("meta.exr");
  write_exr(p, test_image(4, 4), {.metadata = metadata});
  EXPECT_EQ(read_exr(p).metadata, metadata);

  for (const char* reserved : {"channels", "dataWindow", "compression", "expTime", "chromaticities"}) {
    const std::string msg =
        image_error_message([&] { write_exr(p, test_image(4, 4), {.metadata = {{reserved, "x"}}}); });
    EXPECT_NE(msg.find(reserved), std::string::npos) << msg;
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
  }
}

// Writes a file with only a Y channel, half, plus int and double attributes, as another tool might.
TEST_F(ImageExr, YOnlyReadsAsGreyWithIntAndDoubleMetadata) {
  const fs::path p = file("grey.exr");
  const int w = 5, h = 3;
  std::vector<half> y(w * h);
  for (int i = 0; i < w * h; ++i) y[i] = half(0.25f * float(i + 1));
  Imf::Header header(w, h);
  header.channels().insert("Y", Imf::Channel(Imf::HALF));
  header.insert("frame", Imf::IntAttribute(42));
  header.insert("exposureValue", Imf::DoubleAttribute(0.1));
  {
    Imf::OutputFile out(p.c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert("Y", Imf::Slice::Make(Imf::HALF, y.data(), header.dataWindow()));
    out.setFrameBuffer(fb);
    out.writePixels(h);
  }
  const ExrImage back = read_exr(p);
  ASSERT_EQ(back.pixels.width, w);
  ASSERT_EQ(back.pixels.height, h);
  for (int yy = 0; yy < h; ++yy)
    for (int x = 0; x < w; ++x) EXPECT_EQ(back.pixels.at(x, yy), Vec3(0.25f * float(yy * w + x + 1))) << x << "," << yy;
  EXPECT_TRUE(back.pixels.extra.empty());
  EXPECT_EQ(back.metadata.at("frame"), "42");
  EXPECT_EQ(back.metadata.at("exposureValue"), "0.1");
}

TEST_F(ImageExr, ReadsTiledFile) {
  const fs::path p = file("tiled.exr");
  const Image img = test_image(11, 9);
  const Imath::Box2i dw({-3, 2}, {7, 10});
  Imf::Header header(Imath::Box2i({0, 0}, {15, 15}), dw);
  header.setTileDescription(Imf::TileDescription(4, 4, Imf::ONE_LEVEL));
  Imf::FrameBuffer fb;
  for (int c = 0; c < 3; ++c) {
    const char* name = c == 0 ? "R" : c == 1 ? "G" : "B";
    header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    fb.insert(name, Imf::Slice::Make(Imf::FLOAT, img.rgb.data() + c, dw, 3 * sizeof(float), 3 * sizeof(float) * 11));
  }
  {
    Imf::TiledOutputFile out(p.c_str(), header);
    out.setFrameBuffer(fb);
    out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
  }
  const ExrImage back = read_exr(p);
  EXPECT_EQ(back.data_window, (PixelWindow{-3, 2, 8, 11}));
  EXPECT_EQ(back.display_window, (PixelWindow{0, 0, 16, 16}));
  EXPECT_TRUE(same_bits(back.pixels.rgb, img.rgb));
}

TEST_F(ImageExr, ReadsLuminanceChromaFile) {
  const fs::path p = file("yc.exr");
  const int w = 8, h = 6;
  std::vector<Imf::Rgba> pixels(w * h, Imf::Rgba(0.2f, 0.4f, 0.6f, 1.f));
  {
    Imf::RgbaOutputFile out(p.c_str(), w, h, Imf::WRITE_YCA);
    out.setFrameBuffer(pixels.data(), 1, w);
    out.writePixels(h);
  }
  const ExrImage back = read_exr(p);
  ASSERT_EQ(back.pixels.width, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Vec3 c = back.pixels.at(x, y);
      EXPECT_NEAR(c.x, 0.2f, 0.01f);
      EXPECT_NEAR(c.y, 0.4f, 0.01f);
      EXPECT_NEAR(c.z, 0.6f, 0.01f);
    }
  ASSERT_TRUE(back.pixels.extra.count("A"));  // alpha is kept as an extra channel
  EXPECT_EQ(back.pixels.extra.at("A")[0], 1.f);
  EXPECT_FALSE(back.pixels.extra.count("Y"));
}

TEST_F(ImageExr, TruncatedFileThrowsNamingThePath) {
  const fs::path good = file("good.exr");
  write_exr(good, test_image(64, 64));
  const std::vector<uint8_t> bytes = read_bytes(good);
  ASSERT_GT(bytes.size(), 1000u);
  const fs::path p = file("truncated.exr");
  for (size_t keep : {size_t(0), size_t(3), size_t(8), size_t(40), bytes.size() / 2, bytes.size() - 1}) {
    write_bytes(p, std::vector<uint8_t>(bytes.begin(), bytes.begin() + std::ptrdiff_t(keep)));
    const std::string msg = image_error_message([&] { read_exr(p); });
    EXPECT_NE(msg.find(p.string()), std::string::npos) << keep << ": " << msg;
  }
}

TEST_F(ImageExr, NonExrAndMissingFilesThrowNamingThePath) {
  const fs::path text = file("notes.exr");
  std::ofstream(text) << "this is not an OpenEXR file, just some text\n";
  std::string msg = image_error_message([&] { read_exr(text); });
  EXPECT_NE(msg.find(text.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("not an OpenEXR file"), std::string::npos) << msg;
  std::ofstream(text, std::ios::trunc) << "abc";  // shorter than the magic number
  msg = image_error_message([&] { read_exr(text); });
  EXPECT_NE(msg.find("not an OpenEXR file"), std::string::npos) << msg;

  const fs::path png = file("image.png");
  write_png_srgb(png, test_image(4, 4));
  msg = image_error_message([&] { read_exr(png); });
  EXPECT_NE(msg.find(png.string()), std::string::npos) << msg;

  const fs::path missing = file("missing.exr");
  msg = image_error_message([&] { read_exr(missing); });
  EXPECT_NE(msg.find(missing.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("No such file"), std::string::npos) << msg;

  msg = image_error_message([&] { read_exr(dir_); });  // a directory
  EXPECT_NE(msg.find(dir_.string()), std::string::npos) << msg;
}

TEST_F(ImageExr, FileWithoutColourChannelsThrows) {
  const fs::path p = file("depth.exr");
  std::vector<float> z(4 * 4, 1.f);
  Imf::Header header(4, 4);
  header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
  {
    Imf::OutputFile out(p.c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert("Z", Imf::Slice::Make(Imf::FLOAT, z.data(), header.dataWindow()));
    out.setFrameBuffer(fb);
    out.writePixels(4);
  }
  const std::string msg = image_error_message([&] { read_exr(p); });
  EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("channels: Z"), std::string::npos) << msg;
}

// Rewrites the dataWindow attribute of an EXR file in place.
void patch_data_window(std::vector<uint8_t>& bytes, int32_t max_x, int32_t max_y) {
  const std::string key("dataWindow\0box2i\0", 17);
  auto it = std::search(bytes.begin(), bytes.end(), key.begin(), key.end());
  ASSERT_NE(it, bytes.end());
  const size_t at = size_t(it - bytes.begin()) + key.size() + 4;  // after the 4-byte attribute size
  const int32_t box[4] = {0, 0, max_x, max_y};                    // little-endian on the test machines
  std::memcpy(bytes.data() + at, box, sizeof box);
}

TEST_F(ImageExr, AbsurdSizesAreRejected) {
  const fs::path good = file("good.exr");
  write_exr(good, test_image(8, 8));
  const fs::path p = file("huge.exr");
  // Over 65536 wide, over 65536 high, and 65536 x 65536 = 2^32 pixels (over 2^28); then a height OpenEXR itself
  // refuses.
  for (auto [max_x, max_y] :
       {std::pair{65536, 0}, std::pair{0, 1 << 20}, std::pair{65535, 65535}, std::pair{0, 1 << 30}}) {
    std::vector<uint8_t> bytes = read_bytes(good);
    patch_data_window(bytes, max_x, max_y);
    write_bytes(p, bytes);
    const std::string msg = image_error_message([&] { read_exr(p); });
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
    if (max_y == 65535) {
      EXPECT_NE(msg.find("65536x65536 = 4294967296 pixels is over the limit of 268435456"), std::string::npos) << msg;
    } else if (max_y != 1 << 30) {
      EXPECT_NE(msg.find("supported size"), std::string::npos) << msg;
    }
  }
}

// A caller's bound on the data window is checked from the header: a 16384 x 16384 claim in a file of a few hundred
// bytes is refused as ExrTooLarge (with the numbers) before a pixel is allocated, and an image exactly at the bound
// reads.
TEST_F(ImageExr, ACallersPixelBoundIsCheckedFromTheHeader) {
  const fs::path good = file("good.exr");
  write_exr(good, test_image(8, 8));
  EXPECT_EQ(read_exr(good, {.max_pixels = 64}).pixels.width, 8);
  const std::string small = image_error_message([&] { read_exr(good, {.max_pixels = 63}); });
  EXPECT_NE(small.find("data window 8x8 = 64 pixels is over the limit of 63"), std::string::npos) << small;

  std::vector<uint8_t> bytes = read_bytes(good);
  patch_data_window(bytes, 16383, 16383);
  const fs::path p = file("claims.exr");
  write_bytes(p, bytes);
  try {
    read_exr(p, {.max_pixels = 1 << 20});
    ADD_FAILURE() << "did not throw";
  } catch (const ExrTooLarge& e) {
    EXPECT_EQ(e.width, 16384);
    EXPECT_EQ(e.height, 16384);
    EXPECT_EQ(e.limit, 1u << 20);
    EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
  }
  // A bound above the most read_exr decodes is that most.
  try {
    decode_exr(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), {.max_pixels = 1 << 27});
    ADD_FAILURE() << "did not throw";
  } catch (const ExrTooLarge& e) {
    EXPECT_EQ(e.limit, 1u << 27);
  }
}

// colour_only reads the colour and neither allocates nor reads the other channels.
TEST_F(ImageExr, ColourOnlyLeavesExtraChannelsOut) {
  Image img = test_image(6, 4);
  img.extra["variance.R"] = std::vector<float>(24, 0.5f);
  img.uint_extra["samples"] = std::vector<uint32_t>(24, 7u);
  const fs::path p = file("extra.exr");
  write_exr(p, img);
  const ExrImage all = read_exr(p);
  EXPECT_EQ(all.pixels.extra.size(), 1u);
  EXPECT_EQ(all.pixels.uint_extra.size(), 1u);
  const ExrImage colour = read_exr(p, {.colour_only = true});
  EXPECT_TRUE(colour.pixels.extra.empty());
  EXPECT_TRUE(colour.pixels.uint_extra.empty());
  EXPECT_TRUE(same_bits(colour.pixels.rgb, all.pixels.rgb));
}

// OpenEXR's C++ library allocates what a string attribute or a preview image claims before it reads the value: such
// claims beyond the file's end are refused first (a 268-byte file claiming a 1.9 GB comment made read_exr allocate
// 1.9 GB before it found the data missing).
TEST_F(ImageExr, AttributesClaimingMoreThanTheFileHoldsAreRefusedBeforeOpenExrAllocates) {
  const fs::path p = file("claims.exr");
  ExrWriteOptions o;
  o.metadata = {{"comment", "seed"}};
  write_exr(p, test_image(4, 4), o);
  std::vector<uint8_t> bytes = read_bytes(p);
  const std::string key("comment\0string\0", 15);
  const auto it = std::search(bytes.begin(), bytes.end(), key.begin(), key.end());
  ASSERT_NE(it, bytes.end());
  const int32_t huge = 1979711492;  // little-endian on the test machines
  std::memcpy(&*it + key.size(), &huge, sizeof huge);
  write_bytes(p, bytes);
  std::string msg = image_error_message([&] { read_exr(p); });
  EXPECT_NE(msg.find("'comment' (string) claims 1979711492 bytes"), std::string::npos) << msg;
  msg = image_error_message([&] { decode_exr(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size())); });
  EXPECT_NE(msg.find("'comment' (string) claims"), std::string::npos) << msg;

  // A preview image of 2x2 whose header then claims 60000 x 60000 pixels (14 GB) in its 24 bytes.
  {
    Imf::Header h(4, 4);
    Imf::PreviewRgba pixels[4];
    h.setPreviewImage(Imf::PreviewImage(2, 2, pixels));
    Image img = test_image(4, 4);
    Imf::FrameBuffer fb;
    for (int c = 0; c < 3; ++c) {
      h.channels().insert(std::string(1, "RGB"[c]), Imf::Channel(Imf::FLOAT));
      fb.insert(std::string(1, "RGB"[c]), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(img.rgb.data() + c), 12, 48));
    }
    Imf::OutputFile out(p.c_str(), h);
    out.setFrameBuffer(fb);
    out.writePixels(4);
  }
  ExrImage fine = read_exr(p);  // as written, the file reads
  EXPECT_EQ(fine.pixels.width, 4);
  bytes = read_bytes(p);
  const std::string preview("preview\0preview\0", 16);
  const auto at = std::search(bytes.begin(), bytes.end(), preview.begin(), preview.end());
  ASSERT_NE(at, bytes.end());
  const uint32_t side = 60000;
  std::memcpy(&*at + preview.size() + 4, &side, 4);
  std::memcpy(&*at + preview.size() + 8, &side, 4);
  write_bytes(p, bytes);
  msg = image_error_message([&] { read_exr(p); });
  EXPECT_NE(msg.find("'preview' (preview) claims a 60000x60000 image"), std::string::npos) << msg;
}

// OpenEXR reads a typed value by its type whatever size the attribute declares, so a value that does not fill its
// attribute would make its reading drift off the attributes' bounds (where the fuzzer found a 1.9 GB claim read from
// inside a channel list): such attributes are refused.
TEST_F(ImageExr, AttributesWhoseValueDoesNotFillThemAreRefused) {
  const fs::path p = file("drift.exr");
  write_exr(p, test_image(4, 4));
  const std::vector<uint8_t> good = read_bytes(p);
  // Grows the named attribute's declared size by `extra` and inserts that many bytes at the value's end.
  const auto grown = [&](const std::string& name_and_type, int32_t extra) {
    std::vector<uint8_t> bytes = good;
    const auto it = std::search(bytes.begin(), bytes.end(), name_and_type.begin(), name_and_type.end());
    EXPECT_NE(it, bytes.end());
    const size_t size_at = size_t(it - bytes.begin()) + name_and_type.size();
    int32_t size = 0;
    std::memcpy(&size, bytes.data() + size_at, 4);
    const int32_t bigger = size + extra;
    std::memcpy(bytes.data() + size_at, &bigger, 4);
    bytes.insert(bytes.begin() + std::ptrdiff_t(size_at + 4 + size_t(size)), size_t(extra), uint8_t('x'));
    return bytes;
  };
  write_bytes(p, grown(std::string("channels\0chlist\0", 16), 20));
  std::string msg = image_error_message([&] { read_exr(p); });
  EXPECT_NE(msg.find("'channels' (chlist) ends its channel list before the attribute's end"), std::string::npos) << msg;
  write_bytes(p, grown(std::string("dataWindow\0box2i\0", 17), 1));
  msg = image_error_message([&] { read_exr(p); });
  EXPECT_NE(msg.find("'dataWindow' (box2i) holds 17 bytes, its type 16"), std::string::npos) << msg;
}

TEST_F(ImageExr, ReadsCourseBricksTexture) {
  const fs::path p = fs::path(TESSERA_COURSE_DIR) / "assets/bricks.exr";
  const ExrImage bricks = read_exr(p);
  EXPECT_GT(bricks.pixels.width, 0);
  EXPECT_GT(bricks.pixels.height, 0);
  EXPECT_EQ(bricks.pixels.rgb.size(), 3 * size_t(bricks.pixels.width) * size_t(bricks.pixels.height));
  const auto& rgb = bricks.pixels.rgb;
  EXPECT_TRUE(std::all_of(rgb.begin(), rgb.end(), [](float v) { return std::isfinite(v); }));
}

TEST_F(ImageExr, WriteRejectsMalformedImages) {
  const fs::path p = file("bad.exr");
  const Image good = test_image(4, 3);
  EXPECT_THROW(write_exr(p, Image{}), ImageError);                                 // empty
  EXPECT_THROW(write_exr(p, good, {.data_window = {0, 0, 5, 3}}), ImageError);    // window size mismatch
  Image short_rgb = good;
  short_rgb.rgb.pop_back();
  EXPECT_THROW(write_exr(p, short_rgb), ImageError);
  Image bad_extra = good;
  bad_extra.extra["samples"] = std::vector<float>(5, 1.f);
  EXPECT_THROW(write_exr(p, bad_extra), ImageError);
  Image colliding = good;
  colliding.extra["G"] = std::vector<float>(12, 1.f);
  EXPECT_THROW(write_exr(p, colliding), ImageError);
  EXPECT_FALSE(fs::exists(p));
  EXPECT_TRUE(fs::is_empty(p.parent_path()));  // no temp file either
}

// Decodes an 8-bit RGB PNG with libpng's simplified API.
std::vector<uint8_t> decode_png(const std::vector<uint8_t>& png, int& w, int& h) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, png.data(), png.size())) {
    ADD_FAILURE() << image.message;
    return {};
  }
  image.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) ADD_FAILURE() << image.message;
  w = int(image.width);
  h = int(image.height);
  return pixels;
}

TEST_F(ImagePng, SignatureSizeAndSrgbChunk) {
  const std::vector<uint8_t> png = encode_png_srgb(test_image(33, 17));
  ASSERT_GT(png.size(), 33u);
  const uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_EQ(std::memcmp(png.data(), signature, 8), 0);
  EXPECT_EQ(std::string(png.begin() + 12, png.begin() + 16), "IHDR");
  const auto be32 = [&](size_t at) {
    return uint32_t(png[at]) << 24 | uint32_t(png[at + 1]) << 16 | uint32_t(png[at + 2]) << 8 | png[at + 3];
  };
  EXPECT_EQ(be32(16), 33u);
  EXPECT_EQ(be32(20), 17u);
  EXPECT_EQ(png[24], 8);  // bit depth
  EXPECT_EQ(png[25], 2);  // colour type RGB
  const std::string text(png.begin(), png.end());
  EXPECT_NE(text.find("sRGB"), std::string::npos);
  EXPECT_THROW(encode_png_srgb(Image{}), ImageError);
}

TEST_F(ImagePng, SrgbEncodingExposureAndClamping) {
  Image img = Image::make(4, 2);
  img.set(0, 0, Vec3(0.5f));
  img.set(1, 0, {0.f, 1.f, 2.f});
  img.set(2, 0, {-1.f, std::nanf(""), kInfinity});
  img.set(3, 0, {0.001f, 0.0031308f, 0.8f});
  img.set(0, 1, Vec3(0.25f));
  int w = 0, h = 0;
  const std::vector<uint8_t> px = decode_png(encode_png_srgb(img), w, h);
  ASSERT_EQ(w, 4);
  ASSERT_EQ(h, 2);
  const auto pixel = [&](int x, int y, int c) { return int(px[size_t(3 * (y * w + x) + c)]); };
  EXPECT_EQ(pixel(0, 0, 0), 188);  // sRGB(0.5) = 0.7354 -> 187.5 -> 188
  EXPECT_EQ(pixel(1, 0, 0), 0);
  EXPECT_EQ(pixel(1, 0, 1), 255);
  EXPECT_EQ(pixel(1, 0, 2), 255);  // clamped
  EXPECT_EQ(pixel(2, 0, 0), 0);    // negative
  EXPECT_EQ(pixel(2, 0, 1), 0);    // NaN
  EXPECT_EQ(pixel(2, 0, 2), 255);  // +inf
  EXPECT_EQ(pixel(3, 0, 0), 3);    // linear segment: 12.92 * 0.001 * 255 = 3.29
  EXPECT_EQ(pixel(3, 0, 1), 10);   // the segment boundary: 0.04045 * 255 = 10.3
  EXPECT_EQ(pixel(3, 0, 2), 231);  // sRGB(0.8) = 0.9063 -> 231.1
  EXPECT_EQ(pixel(0, 1, 0), 137);  // sRGB(0.25) = 0.5371 -> 136.97

  const std::vector<uint8_t> exposed = decode_png(encode_png_srgb(img, 2.f), w, h);
  EXPECT_EQ(exposed[size_t(3 * (1 * w + 0))], 188);  // 0.25 * 2
}

TEST_F(ImageAtomic, WritesLeaveNoTemporaryBehind) {
  const fs::path exr = file("frame.exr");
  const fs::path png = file("frame.png");
  for (int round = 0; round < 2; ++round) {  // the second round replaces existing files
    const Image img = test_image(10, 6, uint32_t(round + 1));
    write_exr(exr, img);
    write_png_srgb(png, img);
    EXPECT_TRUE(same_bits(read_exr(exr).pixels.rgb, img.rgb));
    EXPECT_EQ(read_bytes(png), encode_png_srgb(img));
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 2);  // no temp file left
}

TEST_F(ImageAtomic, FailedWriteKeepsTheOldFile) {
  const fs::path exr = file("frame.exr");
  const Image img = test_image(10, 6);
  write_exr(exr, img);
  const std::vector<uint8_t> before = read_bytes(exr);
  EXPECT_THROW(write_exr(exr, img, {.metadata = {{"channels", "x"}}}), ImageError);
  Image broken = img;
  broken.rgb.resize(5);
  EXPECT_THROW(write_png_srgb(file("frame.png"), broken), ImageError);
  EXPECT_EQ(read_bytes(exr), before);
  EXPECT_FALSE(fs::exists(file("frame.png")));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);

  const fs::path nowhere = file("no/such/dir/frame.exr");
  std::string msg = image_error_message([&] { write_exr(nowhere, img); });
  EXPECT_NE(msg.find(nowhere.string()), std::string::npos) << msg;
  msg = image_error_message([&] { write_png_srgb(file("no/such/dir/frame.png"), img); });
  EXPECT_NE(msg.find("frame.png"), std::string::npos) << msg;
}

}  // namespace
}  // namespace tessera
