#include "server/preview.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <random>

#include <sys/resource.h>
#include <unistd.h>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

class PreviewOfExr : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("tessera_preview_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

Image random_frame(int width, int height) {
  Image img = Image::make(width, height);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 4.f);
  for (float& v : img.rgb) v = u(rng);
  return img;
}

bool same_bits(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.rgb.size() == b.rgb.size() &&
         std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

// Read a few rows at a time from the file, a frame gives the very preview it gives from memory: scaled (a factor of 3
// with partial edge blocks, and of 1) and with the extra channels of a result ignored.
TEST_F(PreviewOfExr, GivesTheSamePixelsAsTheFrameInMemory) {
  for (const auto& [w, h] : {std::pair{2050, 37}, std::pair{300, 200}}) {
    Image frame = random_frame(w, h);
    frame.uint_extra["state"] = std::vector<uint32_t>(size_t(w) * size_t(h), 5u);
    const fs::path file = dir_ / "result.exr";
    write_exr(file, frame, {.compression = ExrCompression::kNone});
    EXPECT_TRUE(same_bits(preview_image_of_exr(file, w, h), preview_image(&frame, w, h))) << w << "x" << h;
    EXPECT_EQ(preview_png_of_exr(file, w, h), preview_png(&frame, w, h)) << w << "x" << h;
  }
  write_exr(dir_ / "small.exr", random_frame(8, 8));
  try {
    preview_image_of_exr(dir_ / "small.exr", 16, 8);
    ADD_FAILURE() << "a file of another size made a preview";
  } catch (const ImageError& e) {
    EXPECT_NE(std::string(e.what()).find("is not the job's 16x8 frame"), std::string::npos) << e.what();
  }
}

// The preview of a 4096 x 4096 float result (192 MiB of pixels) is made with the process's peak memory growing by far
// less than the frame: a few rows of it are held at a time. The file is written band by band, so that nothing before
// the preview holds the frame either.
TEST_F(PreviewOfExr, AFinishedLargeFrameIsNeverHeldWhole) {
  constexpr int kSide = 4096, kBand = 64;
  const fs::path file = dir_ / "large.exr";
  {
    Imf::Header header(kSide, kSide);
    header.compression() = Imf::NO_COMPRESSION;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    Imf::OutputFile out(file.c_str(), header, 0);
    std::vector<float> band(3 * size_t(kSide) * kBand);
    for (int y0 = 0; y0 < kSide; y0 += kBand) {
      for (int y = y0; y < y0 + kBand; ++y)
        for (int x = 0; x < kSide; ++x) {
          float* rgb = &band[3 * (size_t(y - y0) * kSide + size_t(x))];
          rgb[0] = x % 4 == 0 && y % 4 == 0 ? 1.f : 0.f;
          rgb[1] = 1.f;
          rgb[2] = float(y) / kSide;
        }
      const intptr_t origin = intptr_t(band.data()) - intptr_t(y0) * intptr_t(3 * sizeof(float) * kSide);
      Imf::FrameBuffer fb;
      const char* const names[] = {"R", "G", "B"};
      for (size_t c = 0; c < 3; ++c)
        fb.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(origin + intptr_t(c * sizeof(float))),
                                       3 * sizeof(float), 3 * sizeof(float) * kSide));
      out.setFrameBuffer(fb);
      out.writePixels(kBand);
    }
  }
  rusage before{};
  ::getrusage(RUSAGE_SELF, &before);
  const Image preview = preview_image_of_exr(file, kSide, kSide);
  rusage after{};
  ::getrusage(RUSAGE_SELF, &after);
  const long grown_kib = after.ru_maxrss - before.ru_maxrss;
  std::printf("peak memory grew by %ld KiB making the preview of a %d MiB frame\n", grown_kib,
              int(size_t(kSide) * kSide * 12 >> 20));
  EXPECT_LT(grown_kib, 32 * 1024) << "peak memory grew by more than 32 MiB (in KiB)";
  ASSERT_EQ(preview.width, 1024);
  ASSERT_EQ(preview.height, 1024);
  // Each 4 x 4 block holds one R = 1 at its corner; G is 1 everywhere; B is the mean of its rows' y / 4096.
  EXPECT_EQ(preview.at(0, 0), Vec3(1.f / 16.f, 1.f, (0.f + 1.f + 2.f + 3.f) / 4.f / kSide));
  EXPECT_EQ(preview.at(1023, 1023).x, 1.f / 16.f);
}

}  // namespace
}  // namespace tessera::server
