// `tessera render` with --target-error and the strategy overrides, run as a process: the options reach the
// renderer, a whole image and odd-sized crops agree bitwise, the samples channel holds per-pixel counts, strategies
// agree in expectation, and a bad option is refused with its exit status and message.
#include "core/image/image.h"
#include "tests/support/test_error.h"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace tessera {
namespace {

namespace fs = std::filesystem;

struct Fixture : ::testing::Test {
  fs::path dir;
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("tessera_cli_" + std::to_string(getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir);
    std::ofstream(dir / "scene.json") << R"({
      "integrator": {"type": "intersection_test", "spp": 8, "point_light_flux": [0, 0, 0]},
      "film": {"resolution": [37, 23]},
      "camera": {"position": [0, 2.2, 5], "look_at": [0, 0.4, 0], "fov": 40},
      "textures": {"white": {"type": "constant", "color": [0.8, 0.8, 0.8]},
                   "sky": {"type": "constant", "color": [0.3, 0.4, 0.5]}},
      "materials": {"white": {"type": "diffuse", "texture_name": "white"}},
      "objects": [
        {"type": "sphere", "center": [0, -1000, 0], "radius": 1000, "material_name": "white"},
        {"type": "sphere", "center": [0, 0.8, 0], "radius": 0.45, "material_name": "white"},
        {"type": "sphere", "center": [0.3, 2.6, -0.3], "radius": 0.6, "light": {"type": "area", "radiance": [6, 6, 6]}}
      ],
      "environment_map": {"texture_name": "sky"}
    })";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  int tessera(const std::string& args) {
    const std::string cmd = std::string(TESSERA_BINARY) + " render -q " + (dir / "scene.json").string() + " " + args +
                            " 2>" + (dir / "stderr.txt").string();
    return std::system(cmd.c_str());
  }
  std::string stderr_text() const {
    std::ifstream in(dir / "stderr.txt");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
};

TEST_F(Fixture, TargetErrorWholeAndOddCropsAreBitwiseIdentical) {
  const std::string opts = " --target-error 0.2 --min-spp 4 --max-spp 64 --variance --env-sampling uniform --bvh median";
  ASSERT_EQ(0, tessera("-o " + (dir / "whole.exr").string() + opts));
  const ExrImage whole = read_exr(dir / "whole.exr");
  EXPECT_EQ("adaptive", whole.metadata.at("tessera:spp"));
  EXPECT_EQ("uniform", whole.metadata.at("tessera:envSampling"));
  const auto& spp = whole.pixels.extra.at("samples");
  EXPECT_EQ(8.f, *std::min_element(spp.begin(), spp.end()));  // the first round with n >= 1/E
  EXPECT_EQ(64.f, *std::max_element(spp.begin(), spp.end()));
  for (const PixelWindow w : {PixelWindow{3, 2, 20, 17}, PixelWindow{36, 0, 37, 23}, PixelWindow{0, 11, 37, 12}}) {
    const fs::path out = dir / "crop.exr";
    ASSERT_EQ(0, tessera("-o " + out.string() + opts + " --tile 5 --crop " + std::to_string(w.x0) + " " +
                         std::to_string(w.y0) + " " + std::to_string(w.x1) + " " + std::to_string(w.y1)));
    const ExrImage crop = read_exr(out);
    ASSERT_EQ(w, crop.data_window);
    for (int y = w.y0; y < w.y1; ++y)
      for (int x = w.x0; x < w.x1; ++x) {
        const Vec3 a = whole.pixels.at(x, y), b = crop.pixels.at(x - w.x0, y - w.y0);
        ASSERT_EQ(0, std::memcmp(&a, &b, sizeof a)) << x << "," << y;
        const size_t iw = size_t(y) * 37 + size_t(x), ic = size_t(y - w.y0) * size_t(w.width()) + size_t(x - w.x0);
        ASSERT_EQ(spp[iw], crop.pixels.extra.at("samples")[ic]);
      }
  }
}

TEST_F(Fixture, StrategyOverridesChangeTheImageButNotItsExpectation) {
  // Unbiased per-pixel error estimates (4 replicates), so the two images' difference can be held to them.
  const std::string opts = " --spp 64 --variance --replicates 4";
  ASSERT_EQ(0, tessera("-o " + (dir / "a.exr").string() + opts + " --area-sampling solid_angle"));
  ASSERT_EQ(0, tessera("-o " + (dir / "b.exr").string() + opts + " --area-sampling area"));
  const ExrImage a = read_exr(dir / "a.exr"), b = read_exr(dir / "b.exr");
  EXPECT_EQ("solid_angle", a.metadata.at("tessera:areaSampling"));
  EXPECT_EQ("area", b.metadata.at("tessera:areaSampling"));
  EXPECT_NE(a.pixels.rgb, b.pixels.rgb);
  // The same expectation: the difference is what both images' own error estimates predict, in the sum of squares
  // and in the signed sum (a bias of one strategy moves the signed sum by many of its standard deviations).
  const testing::ErrorCheck c = testing::compare_with_reference(a.pixels, b.pixels);
  std::printf("solid angle vs area: measured %.4g, predicted %.4g (sd %.2g); mean difference at %.2f sd\n", c.measured,
              c.predicted, c.sd, c.bias_z);
  EXPECT_LE(c.measured, 1.2 * c.predicted + 3 * c.sd);
  EXPECT_LE(std::abs(c.bias_z), 4.0);
}

TEST_F(Fixture, AnUnknownBvhIsRejectedWithTheChoices) {
  const int status = tessera("-o " + (dir / "c.exr").string() + " --bvh octree");
  ASSERT_TRUE(WIFEXITED(status)) << "ended by a signal (status " << status << ")";
  EXPECT_EQ(2, WEXITSTATUS(status)) << "a refused command line exits 2";  // 127: binary missing
  EXPECT_NE(std::string::npos, stderr_text().find("--bvh: octree not in {sah,median}")) << stderr_text();
  EXPECT_FALSE(fs::exists(dir / "c.exr"));
}

}  // namespace
}  // namespace tessera
