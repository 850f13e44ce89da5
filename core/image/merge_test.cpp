#include "core/image/merge.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tessera {
namespace {

// A 'full' image whose pixel values encode their position, so misplaced pixels are caught.
Image reference(int w, int h) {
  Image img = Image::make(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.set(x, y, Vec3(float(x), float(y), float(x * 1000 + y) + 0.5f));
  return img;
}

// The crop [win] of img as `tessera render --crop` would write it inside display.
MergeInput crop(const std::string& name, const Image& img, const PixelWindow& display, const PixelWindow& win) {
  MergeInput in;
  in.name = name;
  in.image.display_window = display;
  in.image.data_window = win;
  in.image.pixels = Image::make(win.width(), win.height());
  for (int y = win.y0; y < win.y1; ++y)
    for (int x = win.x0; x < win.x1; ++x) in.image.pixels.set(x - win.x0, y - win.y0, img.at(x - display.x0, y - display.y0));
  return in;
}

TEST(MaskToRectangles, JoinsEqualRunsOfConsecutiveRows) {
  const PixelWindow frame{10, 20, 16, 24};  // 6 x 4
  // Row 0: ##..##   Row 1: ##..##   Row 2: ######   Row 3: ......
  const std::vector<uint8_t> mask = {1, 1, 0, 0, 1, 1,  //
                                     1, 1, 0, 0, 1, 1,  //
                                     1, 1, 1, 1, 1, 1,  //
                                     0, 0, 0, 0, 0, 0};
  const auto r = mask_to_rectangles(mask, frame);
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r[0], (PixelWindow{10, 20, 12, 22}));
  EXPECT_EQ(r[1], (PixelWindow{14, 20, 16, 22}));
  EXPECT_EQ(r[2], (PixelWindow{10, 22, 16, 23}));
}

TEST(MaskToRectangles, WholeFrameIsOneRectangleAndEmptyMaskNone) {
  const PixelWindow frame{0, 0, 5, 3};
  EXPECT_EQ(mask_to_rectangles(std::vector<uint8_t>(15, 1), frame), (std::vector<PixelWindow>{frame}));
  EXPECT_TRUE(mask_to_rectangles(std::vector<uint8_t>(15, 0), frame).empty());
}

TEST(FormatRegions, ListsAtMostMaxAndCountsPixels) {
  const std::vector<PixelWindow> r = {{0, 0, 2, 2}, {4, 0, 5, 1}, {0, 5, 1, 6}};
  EXPECT_EQ(format_regions(r), "[0,2) x [0,2), [4,5) x [0,1), [0,1) x [5,6) (6 pixels)");
  EXPECT_EQ(format_regions(r, 1), "[0,2) x [0,2) and 2 more (6 pixels)");
  EXPECT_EQ(format_regions({{3, 3, 4, 4}}), "[3,4) x [3,4) (1 pixel)");
}

TEST(MergeTiles, AssemblesTilesThatDoNotDivideTheImage) {
  const PixelWindow display{0, 0, 10, 7};
  const Image img = reference(10, 7);
  std::vector<MergeInput> in;
  for (int y = 0; y < 7; y += 4)
    for (int x = 0; x < 10; x += 4)
      in.push_back(crop("t" + std::to_string(in.size()), img, display, {x, y, std::min(x + 4, 10), std::min(y + 4, 7)}));
  const MergeResult r = merge_tiles(in);
  EXPECT_EQ(r.display_window, display);
  EXPECT_EQ(r.image.rgb, img.rgb);
  EXPECT_EQ(r.overlap_pixels, 0);
}

TEST(MergeTiles, HonoursADisplayWindowNotAtTheOrigin) {
  const PixelWindow display{-3, 5, 3, 9};
  const Image img = reference(6, 4);
  const MergeResult r =
      merge_tiles({crop("a", img, display, {-3, 5, 0, 9}), crop("b", img, display, {0, 5, 3, 9})});
  EXPECT_EQ(r.image.rgb, img.rgb);
}

TEST(MergeTiles, AcceptsIdenticalOverlaps) {
  const PixelWindow display{0, 0, 8, 8};
  const Image img = reference(8, 8);
  const MergeResult r = merge_tiles({crop("a", img, display, {0, 0, 8, 8}), crop("b", img, display, {2, 2, 5, 4})});
  EXPECT_EQ(r.image.rgb, img.rgb);
  EXPECT_EQ(r.overlap_pixels, 6);
}

TEST(MergeTiles, ReportsAMissingTileAsOneRectangle) {
  const PixelWindow display{0, 0, 64, 64};
  const Image img = reference(64, 64);
  std::vector<MergeInput> in = {crop("a.exr", img, display, {0, 0, 32, 32}), crop("b.exr", img, display, {0, 32, 32, 64}),
                                crop("c.exr", img, display, {32, 32, 64, 64})};
  try {
    merge_tiles(in);
    FAIL() << "merge of an incomplete set succeeded";
  } catch (const MergeError& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot merge 3 tiles into [0,64) x [0,64):\n  pixels covered by no tile: [32,64) x [0,32) (1024 pixels)");
  }
}

TEST(MergeTiles, ReportsConflictingOverlapsPerPairOfFiles) {
  const PixelWindow display{0, 0, 8, 4};
  const Image img = reference(8, 4);
  MergeInput a = crop("a.exr", img, display, {0, 0, 5, 4});
  MergeInput b = crop("b.exr", img, display, {3, 0, 8, 4});
  // b disagrees with a on column 4 (rows 0..3) and is identical on column 3.
  for (int y = 0; y < 4; ++y) b.image.pixels.set(1, y, Vec3(-1.f));
  try {
    merge_tiles({a, b});
    FAIL() << "merge of conflicting tiles succeeded";
  } catch (const MergeError& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot merge 2 tiles into [0,8) x [0,4):\n"
              "  conflicting overlap of a.exr and b.exr (different values): [4,5) x [0,4) (4 pixels)");
  }
}

TEST(MergeTiles, ReportsGapsAndConflictsTogether) {
  const PixelWindow display{0, 0, 4, 4};
  const Image img = reference(4, 4);
  MergeInput a = crop("a", img, display, {0, 0, 4, 2});
  MergeInput b = crop("b", img, display, {0, 1, 2, 3});
  b.image.pixels.set(0, 0, Vec3(std::nanf("")));  // (0,1) differs
  try {
    merge_tiles({a, b});
    FAIL();
  } catch (const MergeError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("pixels covered by no tile: [2,4) x [2,3), [0,4) x [3,4) (6 pixels)"), std::string::npos) << msg;
    EXPECT_NE(msg.find("conflicting overlap of a and b (different values): [0,1) x [1,2) (1 pixel)"), std::string::npos)
        << msg;
  }
}

TEST(MergeTiles, RejectsMismatchedDisplayWindowsAndStrayDataWindows) {
  const Image img = reference(8, 8);
  MergeInput a = crop("a.exr", img, {0, 0, 8, 8}, {0, 0, 8, 4});
  MergeInput b = crop("b.exr", img, {0, 0, 8, 8}, {0, 4, 8, 8});
  b.image.display_window = {0, 0, 8, 9};
  MergeInput c = crop("c.exr", img, {0, 0, 8, 8}, {0, 4, 8, 8});
  c.image.data_window = {0, 5, 8, 9};
  try {
    merge_tiles({a, b, c});
    FAIL();
  } catch (const MergeError& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot merge 3 tiles:\n"
              "  b.exr has display window [0,8) x [0,9), but a.exr has [0,8) x [0,8)\n"
              "  c.exr has data window [0,8) x [5,9) outside the display window [0,8) x [0,8)");
  }
  EXPECT_THROW(merge_tiles({}), MergeError);
}

TEST(MergeTiles, KeepsMetadataCommonToAllInputs) {
  const PixelWindow display{0, 0, 2, 1};
  const Image img = reference(2, 1);
  MergeInput a = crop("a", img, display, {0, 0, 1, 1});
  MergeInput b = crop("b", img, display, {1, 0, 2, 1});
  a.image.metadata = {{"tessera:spp", "4"}, {"tessera:renderSeconds", "1.0"}, {"only:a", "x"}};
  b.image.metadata = {{"tessera:spp", "4"}, {"tessera:renderSeconds", "2.0"}};
  EXPECT_EQ(merge_tiles({a, b}).metadata, (std::map<std::string, std::string>{{"tessera:spp", "4"}}));
}

}  // namespace
}  // namespace tessera

namespace tessera {
namespace {

TEST(MergeTiles, ExtraChannelsAreMergedAndMustMatch) {
  const PixelWindow display{0, 0, 6, 4};
  const Image full = reference(6, 4);
  MergeInput a = crop("a", full, display, PixelWindow{0, 0, 3, 4});
  MergeInput b = crop("b", full, display, PixelWindow{3, 0, 6, 4});
  a.image.pixels.extra["Z"] = std::vector<float>(12, 2.f);
  b.image.pixels.extra["Z"] = std::vector<float>(12, 5.f);
  const MergeResult m = merge_tiles({a, b});
  ASSERT_EQ(m.image.extra.count("Z"), 1u);
  EXPECT_EQ(m.image.extra.at("Z")[0], 2.f);
  EXPECT_EQ(m.image.extra.at("Z")[5], 5.f);
  // An overlap whose layer differs is a conflict even when the colours agree.
  MergeInput c = crop("c", full, display, PixelWindow{2, 0, 4, 1});
  c.image.pixels.extra["Z"] = std::vector<float>(2, 9.f);
  EXPECT_THROW(merge_tiles({a, b, c}), MergeError);
  b.image.pixels.extra.clear();
  try {
    merge_tiles({a, b});
    FAIL() << "tiles of other channels merged";
  } catch (const MergeError& e) {
    EXPECT_NE(std::string(e.what()).find("b has extra channels none, but a has Z"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace tessera
