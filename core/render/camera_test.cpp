// Camera tests: rays exactly as docs/scene-format.md defines them, with the written image's first row at the top.
#include "core/render/camera.h"

#include "tests/support/test_closed_forms.h"

#include <gtest/gtest.h>

#include <random>

namespace tessera {
namespace {

using testing::Vec3d;

TEST(Camera, RaysFollowTheCourseFormula) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  const Vec3 pos(1.f, 2.f, 3.f), at(-1.f, 0.5f, 0.f), up(0.f, 1.f, 0.f);
  const int w = 7, h = 5;
  const Camera cam = Camera::look_at(pos, at, up, 35.f);
  const testing::CourseCamera ref(Vec3d(pos), Vec3d(at), Vec3d(up), 35.0, w, h);
  for (int k = 0; k < 1000; ++k) {
    const int px = int(U(rng) * w), row = int(U(rng) * h);
    const Vec2 uv(U(rng), U(rng));
    const Ray r = cam.generate_pixel(px, row, uv, w, h);
    const Vec3d film = ref.film_of_pixel(px, row, uv.x, uv.y);
    const Vec3d d = glm::normalize(ref.direction(film.x, film.y));
    EXPECT_NEAR(glm::length(Vec3d(r.d) - d), 0.0, 1e-6);
    EXPECT_EQ(r.o, pos);
  }
}

TEST(Camera, FirstRowIsTheTopAndFirstColumnTheLeft) {
  // Looking down -z with +y up: right is +x.
  const Camera cam = Camera::look_at(Vec3(0.f), Vec3(0.f, 0.f, -1.f), Vec3(0.f, 1.f, 0.f), 90.f);
  const int w = 4, h = 4;
  EXPECT_GT(cam.generate_pixel(1, 0, Vec2(0.5f), w, h).d.y, 0.f);      // top row looks up
  EXPECT_LT(cam.generate_pixel(1, h - 1, Vec2(0.5f), w, h).d.y, 0.f);  // bottom row looks down
  EXPECT_LT(cam.generate_pixel(0, 1, Vec2(0.5f), w, h).d.x, 0.f);      // first column looks left
  EXPECT_GT(cam.generate_pixel(w - 1, 1, Vec2(0.5f), w, h).d.x, 0.f);
  // The corner of the film: pixel (0, 0) at offset (0, 0) is the top-left corner, 45 degrees up and left (fov 90).
  const Vec3 c = cam.generate_pixel(0, 0, Vec2(0.f), w, h).d;
  EXPECT_NEAR(c.x / c.z, 1.f, 1e-6f);   // x = z (both negative)
  EXPECT_NEAR(c.y / -c.z, 1.f, 1e-6f);  // y = -z (positive)
}

TEST(Camera, DegenerateSetupsAreRefused) {
  EXPECT_THROW(Camera::look_at(Vec3(0.f), Vec3(0.f), Vec3(0.f, 1.f, 0.f), 45.f), std::invalid_argument);
  EXPECT_THROW(Camera::look_at(Vec3(0.f), Vec3(0.f, 1.f, 0.f), Vec3(0.f, 1.f, 0.f), 45.f), std::invalid_argument);
  EXPECT_THROW(Camera::look_at(Vec3(0.f), Vec3(0.f, 0.f, -1.f), Vec3(0.f, 1.f, 0.f), 180.f), std::invalid_argument);
}

}  // namespace
}  // namespace tessera
