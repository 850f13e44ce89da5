// Test-only: a private temporary folder per test, and small scene, OBJ and EXR files written into it.
#pragma once

#include "core/image/image.h"
#include "core/scene/scene_loader.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace tessera::testing {

/// A fixture owning a fresh folder (named after the test and the process) that is removed afterwards.
class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::path(::testing::TempDir()) / ("tessera_" + std::to_string(::getpid()) + "_" +
                                                           info->test_suite_name() + "_" + info->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  /// Path of `name` inside the folder.
  std::filesystem::path file(const std::string& name) const { return dir_ / name; }

  /// Writes `text` to `name` (creating sub-folders) and returns the path.
  std::filesystem::path write(const std::string& name, const std::string& text) const {
    const auto p = file(name);
    std::filesystem::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

  /// Writes a scene as JSON text to `name` and returns the path.
  std::filesystem::path write_scene(const std::string& name, const nlohmann::json& scene) const {
    return write(name, scene.dump(2));
  }

  /// Writes an EXR image to `name` and returns the path.
  std::filesystem::path write_image(const std::string& name, const Image& img) const {
    const auto p = file(name);
    std::filesystem::create_directories(p.parent_path());
    write_exr(p, img);
    return p;
  }

  std::filesystem::path dir_;
};

/// OBJ text of the rectangle corner + s*ex + t*ey (two triangles, counter-clockwise seen from cross(ex, ey)),
/// with texture coordinates (s, t) when `uv` is set.
inline std::string rect_obj(const Vec3& corner, const Vec3& ex, const Vec3& ey, bool uv = false) {
  const Vec3 p[4] = {corner, corner + ex, corner + ex + ey, corner + ey};
  std::string s;
  for (const Vec3& v : p) s += "v " + std::to_string(v.x) + " " + std::to_string(v.y) + " " + std::to_string(v.z) + "\n";
  if (!uv) return s + "f 1 2 3\nf 1 3 4\n";
  return s + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
}

/// A minimal valid scene: one diffuse sphere, a constant texture, a small film.
inline nlohmann::json minimal_scene() {
  return nlohmann::json::parse(R"({
    "integrator": {"type": "intersection_test", "spp": 1},
    "film": {"resolution": [4, 3]},
    "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "ref_up": [0, 1, 0], "fov": 45},
    "textures": {"white": {"type": "constant", "color": [1, 1, 1]}},
    "materials": {"white_diffuse": {"type": "diffuse", "texture_name": "white"}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material_name": "white_diffuse"}]
  })");
}

}  // namespace tessera::testing
