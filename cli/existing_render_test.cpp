// Unit tests of cli/existing_render.h: each verdict on a file an earlier render wrote, from files written here with
// the metadata and channels a render writes.
#include "cli/existing_render.h"

#include "core/image/image.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

namespace tessera::cli {
namespace {

namespace fs = std::filesystem;

class ExistingRenderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) / ("tessera_existing_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    RenderArgs args;
    args.seed = 3;
    expected_ = expected_render(args, "abc", 4, 3, 8);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The metadata a render of expected_ writes.
  std::map<std::string, std::string> metadata() const {
    std::map<std::string, std::string> m = expected_.sampling;
    m["tessera:sceneHash"] = "abc";
    m["tessera:version"] = "x";
    return m;
  }
  // Writes a 4x3 render with this metadata (and window, half colours, extra channels) and judges it.
  ExistingRender judge(const std::map<std::string, std::string>& m, ExrWriteOptions o = {},
                       const Image& img = Image::make(4, 3)) {
    const fs::path p = dir_ / "f.exr";
    o.metadata = m;
    if (o.display_window.empty()) o.display_window = {0, 0, 4, 3};
    write_exr(p, img, o);
    return examine_render(p, expected_);
  }
  static Image with_channel(const std::string& name, bool uint) {
    Image img = Image::make(4, 3);
    if (uint) img.uint_extra[name].assign(12, 1u);
    else img.extra[name].assign(12, 1.f);
    return img;
  }

  fs::path dir_;
  ExpectedRender expected_;
};

TEST_F(ExistingRenderTest, CompleteWhenEverythingTheRenderRecordsAgrees) {
  EXPECT_FALSE(examine_render(dir_ / "none.exr", expected_).exists);
  const ExistingRender r = judge(metadata());
  EXPECT_TRUE(r.exists);
  EXPECT_TRUE(r.complete) << r.why_incomplete;
  EXPECT_FALSE(r.continuable);
  EXPECT_EQ(r.why_not_continuable, "is complete");
  // Exact sums that were not asked for do not matter.
  EXPECT_TRUE(judge(metadata(), {}, with_channel("tessera.state.sum.R.hi", true)).complete);
}

TEST_F(ExistingRenderTest, NeitherCompleteNorContinuable) {
  std::ofstream(dir_ / "f.exr") << "not an image";
  ExistingRender r = examine_render(dir_ / "f.exr", expected_);
  EXPECT_TRUE(r.exists);
  EXPECT_FALSE(r.complete || r.continuable);
  EXPECT_EQ(r.why_incomplete, "does not read (not an OpenEXR file (no magic number))");
  auto m = metadata();
  m.erase("tessera:sceneHash");
  EXPECT_EQ(judge(m).why_incomplete, "has no tessera:sceneHash metadata (it was not written by `tessera render`)");
  m = metadata();
  m["tessera:sceneHash"] = "abd";
  r = judge(m);
  EXPECT_EQ(r.why_incomplete, "was rendered from another scene (or other assets)");
  EXPECT_EQ(r.why_not_continuable, r.why_incomplete);
  EXPECT_EQ(judge(metadata(), {.display_window = {0, 0, 5, 3}}).why_incomplete, "is not a 4x3 picture");
  r = judge(metadata(), {.display_window = {0, 0, 4, 3}, .data_window = {0, 0, 2, 3}}, Image::make(2, 3));
  EXPECT_EQ(r.why_incomplete, "is a crop (pixels 0 0 2 3)");
  EXPECT_FALSE(r.continuable);
  m = metadata();
  m["tessera:seed"] = "4";
  r = judge(m);
  EXPECT_EQ(r.why_incomplete, "was rendered with tessera:seed 4, not 3");
  EXPECT_EQ(r.why_not_continuable, r.why_incomplete);
  m = metadata();
  m["tessera:bvhOverride"] = "median";
  EXPECT_EQ(judge(m).why_incomplete, "was rendered with tessera:bvhOverride median, not none");
}

TEST_F(ExistingRenderTest, TheFilesLayoutIsTheCommands) {
  ExistingRender r = judge(metadata(), {.half = true});
  EXPECT_EQ(r.why_incomplete, "holds half-float colours (--half)");
  expected_.half = true;
  EXPECT_EQ(judge(metadata()).why_incomplete, "holds float32 colours, not half floats (--half)");
  expected_.half = false;
  r = judge(metadata(), {}, with_channel("variance.R", false));
  EXPECT_EQ(r.why_incomplete, "has variance channels (--variance)");
  EXPECT_EQ(r.why_not_continuable, r.why_incomplete);
  expected_.variance = true;
  EXPECT_EQ(judge(metadata()).why_incomplete, "has no variance channels (--variance)");
  expected_.variance = false;
  expected_.resumable = true;
  EXPECT_EQ(judge(metadata()).why_incomplete, "holds no exact sample sums (--resumable)");
}

TEST_F(ExistingRenderTest, WhatResumeCanContinue) {
  // A partial render at the same spp is finished.
  auto m = metadata();
  m["tessera:partial"] = "5 of 12 pixels";
  ExistingRender r = judge(m);
  EXPECT_FALSE(r.complete);
  EXPECT_EQ(r.why_incomplete, "is partial (5 of 12 pixels)");
  EXPECT_TRUE(r.continuable) << r.why_not_continuable;
  // ...but not made --resumable without exact sums.
  expected_.resumable = true;
  EXPECT_EQ(judge(m).why_not_continuable, "holds no exact sample sums, so its continuation cannot be --resumable");
  expected_.resumable = false;
  // At fewer spp: only with exact sums, partial or finished.
  m = metadata();
  m["tessera:spp"] = "2";
  r = judge(m);
  EXPECT_EQ(r.why_incomplete, "was rendered with tessera:spp 2, not 8");
  EXPECT_EQ(r.why_not_continuable,
            "holds no exact sample sums (--resumable), so it can only be finished at its own 2 spp");
  r = judge(m, {}, with_channel("tessera.state.sum.R.hi", true));
  EXPECT_TRUE(r.continuable) << r.why_not_continuable;
  m["tessera:partial"] = "5 of 12 pixels";
  EXPECT_TRUE(judge(m, {}, with_channel("tessera.state.sum.R.hi", true)).continuable);
  // At more spp: never.
  m = metadata();
  m["tessera:spp"] = "16";
  r = judge(m, {}, with_channel("tessera.state.sum.R.hi", true));
  EXPECT_EQ(r.why_not_continuable, "was rendered at 16 spp, more than 8");
}

TEST_F(ExistingRenderTest, PixelsThatDoNotReadSpoilAGoodHeader) {
  const fs::path p = dir_ / "f.exr";
  write_exr(p, Image::make(4, 3), {.compression = ExrCompression::kNone, .display_window = {0, 0, 4, 3},
                                   .metadata = metadata()});
  fs::resize_file(p, fs::file_size(p) - 20);
  const ExistingRender r = examine_render(p, expected_);
  EXPECT_FALSE(r.complete);
  EXPECT_EQ(r.why_incomplete.rfind("does not read (", 0), 0u) << r.why_incomplete;
}

TEST(SamplingDifference, NamesTheFirstKeyThatDiffers) {
  const std::map<std::string, std::string> a = {{"tessera:seed", "1"}, {"tessera:spp", "4"}};
  EXPECT_EQ(sampling_difference(a, a), "");
  EXPECT_EQ(sampling_difference(a, {{"tessera:seed", "1"}, {"tessera:spp", "8"}}), "tessera:spp 4, not 8");
  EXPECT_EQ(sampling_difference(a, {{"tessera:seed", "1"}, {"tessera:spp", "8"}}, "tessera:spp"), "");
  EXPECT_EQ(sampling_difference({{"tessera:seed", "1"}}, a), "no tessera:spp, not 4");
  // Keys that are not sampling settings are not compared.
  EXPECT_EQ(sampling_difference({{"tessera:seed", "1"}, {"tessera:spp", "4"}, {"tessera:renderSeconds", "2"}}, a), "");
  EXPECT_TRUE(sampling_keys().count("tessera:targetError"));
  EXPECT_TRUE(sampling_keys().count("tessera:bvhOverride"));
  EXPECT_FALSE(sampling_keys().count("tessera:sceneHash"));
}

}  // namespace
}  // namespace tessera::cli
