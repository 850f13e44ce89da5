#include "core/image/tiles.h"

#include <gtest/gtest.h>

#include <vector>

namespace tessera {
namespace {

// Every pixel belongs to exactly one tile, whatever the tile size, including sizes that do not divide the image.
TEST(TileGrid, TilesPartitionTheImage) {
  for (int w : {1, 7, 64, 65}) {
    for (int h : {1, 5, 64, 130}) {
      for (int ts : {1, 3, 16, 64, 200}) {
        const TileGrid g(w, h, ts);
        std::vector<int> cover(size_t(w) * size_t(h), 0);
        for (int64_t i = 0; i < g.count(); ++i) {
          const PixelWindow win = g.window(i);
          ASSERT_FALSE(win.empty());
          ASSERT_TRUE((PixelWindow{0, 0, w, h}.contains(win)));
          ASSERT_LE(win.width(), ts);
          for (int y = win.y0; y < win.y1; ++y)
            for (int x = win.x0; x < win.x1; ++x) ++cover[size_t(y) * size_t(w) + size_t(x)];
        }
        for (int c : cover) ASSERT_EQ(c, 1) << w << "x" << h << " tile " << ts;
      }
    }
  }
}

TEST(TileGrid, RowMajorFromTopLeft) {
  const TileGrid g(100, 50, 32);
  EXPECT_EQ(g.columns(), 4);
  EXPECT_EQ(g.rows(), 2);
  EXPECT_EQ(g.window(0), (PixelWindow{0, 0, 32, 32}));
  EXPECT_EQ(g.window(3), (PixelWindow{96, 0, 100, 32}));
  EXPECT_EQ(g.window(4), (PixelWindow{0, 32, 32, 50}));
  EXPECT_THROW(TileGrid(0, 1, 1), std::invalid_argument);
}

}  // namespace
}  // namespace tessera
