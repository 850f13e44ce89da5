#include "core/image/contact_sheet.h"

#include <gtest/gtest.h>

namespace tessera {
namespace {

Image constant(int w, int h, float r, float g, float b) {
  Image img;
  img.width = w;
  img.height = h;
  img.rgb.resize(size_t(w) * size_t(h) * 3);
  for (size_t i = 0; i < img.rgb.size(); i += 3) {
    img.rgb[i] = r;
    img.rgb[i + 1] = g;
    img.rgb[i + 2] = b;
  }
  return img;
}

TEST(Thumbnail, AConstantImageGivesAConstantThumbnailOfTheSameAspect) {
  const Image t = thumbnail(constant(64, 32, 0.25f, 0.5f, 2.f), 16);
  EXPECT_EQ(t.width, 16);
  EXPECT_EQ(t.height, 8);
  for (size_t i = 0; i < t.rgb.size(); i += 3) {
    EXPECT_EQ(t.rgb[i], 0.25f);
    EXPECT_EQ(t.rgb[i + 1], 0.5f);
    EXPECT_EQ(t.rgb[i + 2], 2.f);
  }
}

TEST(Thumbnail, AWholeFactorAveragesEachBlock) {
  // 4x2 with distinct values, halved: each output pixel is the mean of its 2x2 block.
  Image img = constant(4, 2, 0, 0, 0);
  for (int i = 0; i < 8; ++i) img.rgb[size_t(i) * 3] = float(i);  // red = 0..7, row-major
  const Image t = thumbnail(img, 2);
  ASSERT_EQ(t.height, 1);
  EXPECT_FLOAT_EQ(t.rgb[0], (0 + 1 + 4 + 5) / 4.f);
  EXPECT_FLOAT_EQ(t.rgb[3], (2 + 3 + 6 + 7) / 4.f);
}

TEST(Thumbnail, RefusesAnEmptyImageAndAZeroWidth) {
  EXPECT_THROW(thumbnail(Image{}, 8), ImageError);
  EXPECT_THROW(thumbnail(constant(4, 4, 1, 1, 1), 0), ImageError);
}

TEST(ContactSheet, LaysOutCellsInRowsWithGaps) {
  // 5 images: 3 columns by default (3 x 3 >= 5), 2 rows; cells 4 wide; row heights 3 and 2.
  std::vector<Image> imgs = {constant(4, 3, 1, 0, 0), constant(4, 2, 0, 1, 0), constant(2, 2, 0, 0, 1),
                             constant(4, 2, 1, 1, 1), constant(3, 1, 1, 1, 0)};
  const Image s = contact_sheet(imgs, 0, 2);
  EXPECT_EQ(s.width, 2 + 3 * (4 + 2));
  EXPECT_EQ(s.height, 2 + 3 + 2 + 2 + 2);
  EXPECT_EQ(s.at(2, 2), Vec3(1, 0, 0));      // the first image's corner
  EXPECT_EQ(s.at(0, 0), Vec3(0, 0, 0));      // the gap
  EXPECT_EQ(s.at(8, 2), Vec3(0, 1, 0));      // second cell starts at 2 + 6
  EXPECT_EQ(s.at(14, 2), Vec3(0, 0, 1));     // third
  EXPECT_EQ(s.at(16, 2), Vec3(0, 0, 0));     // beyond the narrow third image: black
  EXPECT_EQ(s.at(2, 7), Vec3(1, 1, 1));      // second row starts at 2 + 3 + 2
  EXPECT_EQ(s.at(8, 7), Vec3(1, 1, 0));
  EXPECT_EQ(contact_sheet(imgs, 5, 0).width, 5 * 4);
  EXPECT_EQ(contact_sheet(imgs, 9, 0).width, 5 * 4);  // never more columns than images
}

TEST(ContactSheet, RefusesNoImages) { EXPECT_THROW(contact_sheet({}), ImageError); }

}  // namespace
}  // namespace tessera
