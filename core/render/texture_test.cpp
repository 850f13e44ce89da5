// Texture tests: the checkerboard follows docs/scene-format.md (cells 0.5 wide in scale * uv + delta, truncation
// toward zero, parity mod 2 into {0, 1}).
#include "core/render/texture.h"

#include <gtest/gtest.h>

namespace tessera {
namespace {

TEST(Texture, CheckerboardCells) {
  Texture t;
  t.checkerboard = true;
  t.color = Vec3(1.f, 0.f, 0.f);
  t.color1 = Vec3(0.f, 0.f, 1.f);
  EXPECT_EQ(t.evaluate(Vec2(0.1f, 0.1f)), t.color);    // a = b = 0
  EXPECT_EQ(t.evaluate(Vec2(0.6f, 0.1f)), t.color1);   // a = 1, b = 0
  EXPECT_EQ(t.evaluate(Vec2(0.6f, 0.7f)), t.color);    // a = b = 1
  EXPECT_EQ(t.evaluate(Vec2(1.1f, 0.1f)), t.color);    // a = 2 mod 2 = 0
  // Truncation toward zero: s in (-0.5, 0.5) is one cell (a = 0), s in (-1, -0.5] has a = -1 -> 1.
  EXPECT_EQ(t.evaluate(Vec2(-0.2f, 0.1f)), t.color);
  EXPECT_EQ(t.evaluate(Vec2(-0.7f, 0.1f)), t.color1);
  EXPECT_EQ(t.evaluate(Vec2(-0.7f, -0.7f)), t.color);
  // scale and delta apply before the cells.
  t.scale = Vec2(2.f, 1.f);
  EXPECT_EQ(t.evaluate(Vec2(0.3f, 0.1f)), t.color1);   // s = 0.6
  t.delta = Vec2(0.5f, 0.f);
  EXPECT_EQ(t.evaluate(Vec2(0.3f, 0.1f)), t.color);    // s = 1.1
  EXPECT_EQ(t.evaluate(Vec2(1e30f, 0.1f)), t.color);   // huge coordinates: even, no overflow
}

}  // namespace
}  // namespace tessera
