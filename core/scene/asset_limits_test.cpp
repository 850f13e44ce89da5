// The scene loader's asset limits (LoadOptions::asset_limits): an image texture is measured from its header and an
// OBJ mesh from its size and a count of its lines, before either is decoded; a file over a limit is a SceneError
// naming the JSON path, the file, its size and the limit's flag.
#include "core/scene/obj_limits.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

namespace tessera {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

class AssetLimitsTest : public testing::TempDirTest {
 protected:
  // The SceneError message of loading `scene` (written as scene.json) with these limits; "" when it loads.
  std::string error_of(const json& scene, const AssetLimits& limits) {
    LoadOptions o;
    o.asset_limits = limits;
    try {
      load_scene_file(write_scene("scene.json", scene), o);
    } catch (const SceneError& e) {
      return e.what();
    }
    return "";
  }
  json textured_scene(const std::string& path) {
    json s = testing::minimal_scene();
    s["textures"]["img"] = {{"type", "image"}, {"path", path}};
    s["materials"]["white_diffuse"]["texture_name"] = "img";
    return s;
  }
  json mesh_scene(const std::string& path) {
    json s = testing::minimal_scene();
    s["objects"].push_back({{"type", "mesh"}, {"path", path}, {"material_name", "white_diffuse"}});
    return s;
  }
  // An EXR of a few hundred bytes whose header declares a width x height data window (its pixels are a 4x2 image's).
  void write_claiming_exr(const std::string& name, int32_t width, int32_t height) {
    const fs::path p = write_image(name, Image::make(4, 2));
    std::ifstream in(p, std::ios::binary);
    std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    const std::string key("dataWindow\0box2i\0", 17);
    const size_t at = bytes.find(key);
    ASSERT_NE(at, std::string::npos);
    const int32_t box[4] = {0, 0, width - 1, height - 1};  // little-endian on the test machines
    std::memcpy(bytes.data() + at + key.size() + 4, box, sizeof box);
    write(name, bytes);
  }
};

TEST_F(AssetLimitsTest, AnImageOverThePixelLimitIsRefusedWithItsSizeAndTheLimit) {
  write_image("tex/four_by_two.exr", Image::make(4, 2));
  const json scene = textured_scene("tex/four_by_two.exr");
  EXPECT_EQ(error_of(scene, {.max_pixels = 8}), "");
  const std::string msg = error_of(scene, {.max_pixels = 7});
  EXPECT_NE(msg.find(file("scene.json").string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("textures.img.path: tex/four_by_two.exr: image too large: 4x2 = 8 pixels is over the limit of 7 "
                     "(--max-asset-pixels)"),
            std::string::npos)
      << msg;
}

// A header claiming 1073741823 x 1073741823 pixels (12 exabytes of float RGB: allocating it would throw bad_alloc) in
// a file of a few hundred bytes is refused from its header, at once, under the default limits.
TEST_F(AssetLimitsTest, AnImageHeaderClaimingAHugeSizeIsRefusedBeforeAnyPixelIsAllocated) {
  write_claiming_exr("tex/claims.exr", 1073741823, 1073741823);
  ASSERT_LT(fs::file_size(file("tex/claims.exr")), 1024u);
  const auto t0 = std::chrono::steady_clock::now();
  const std::string msg = error_of(textured_scene("tex/claims.exr"), {});
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
  EXPECT_NE(msg.find("tex/claims.exr: image too large: 1073741823x1073741823 = 1152921502459363329 pixels is over "
                     "the limit of 268435456 (--max-asset-pixels)"),
            std::string::npos)
      << msg;
  EXPECT_EQ(msg.find("bad_alloc"), std::string::npos) << msg;
}

TEST_F(AssetLimitsTest, AMeshOverTheTriangleLimitIsRefusedBeforeItIsParsed) {
  write("quads.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\tf 1 2 3 4\r\n");
  const json scene = mesh_scene("quads.obj");
  EXPECT_EQ(error_of(scene, {.max_triangles = 4}), "");
  const std::string msg = error_of(scene, {.max_triangles = 3});
  EXPECT_NE(msg.find("objects[1].path: quads.obj: mesh too large: 4 triangles is over the limit of 3 "
                     "(--max-mesh-triangles)"),
            std::string::npos)
      << msg;
}

TEST_F(AssetLimitsTest, AMeshsVerticesAndBytesAreBoundedByTheTriangleLimit) {
  std::string many_vertices;
  for (int i = 0; i < 7; ++i) many_vertices += "v 0 0 " + std::to_string(i) + "\n";
  write("vertices.obj", many_vertices + "f 1 2 3\n");
  EXPECT_EQ(error_of(mesh_scene("vertices.obj"), {.max_triangles = 3}), "");
  std::string msg = error_of(mesh_scene("vertices.obj"), {.max_triangles = 2});
  EXPECT_NE(msg.find("vertices.obj: mesh too large: 7 vertex positions is over the limit of 6 (3 per triangle of "
                     "--max-mesh-triangles)"),
            std::string::npos)
      << msg;
  // Over 1024 bytes per allowed triangle: refused from the file's size, unread.
  write("padded.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# " + std::string(2100, 'x') + "\n");
  EXPECT_EQ(error_of(mesh_scene("padded.obj"), {.max_triangles = 3}), "");
  msg = error_of(mesh_scene("padded.obj"), {.max_triangles = 2});
  EXPECT_NE(msg.find("padded.obj: mesh too large: " + std::to_string(fs::file_size(file("padded.obj"))) +
                     " bytes is over the limit of 2048 (1024 bytes per triangle of --max-mesh-triangles)"),
            std::string::npos)
      << msg;
}

TEST(ObjCount, CountsWhatTinyObjLoaderReads) {
  const ObjCounts n = count_obj(
      "# f 1 2 3 is a comment\n"
      "v 0 0 0\r\n"
      "  v 1 0 0\n"
      "\tv 1 1 0\rv 0 1 0\n"
      "vn 0 0 1\nvt 0 0\nvt 1 0\nvp 0 0\n"
      "f 1 2 3\n"
      "f 1/1/1 2/2/1 3/1/1 4/2/1\r\n"
      "f\t1 2 3 4 5 6   \n"
      "f 1 2\n"
      "fo 1 2 3\nl 1 2 3\np 1\n"
      "f 1 2 3");
  EXPECT_EQ(n.positions, 4u);
  EXPECT_EQ(n.normals, 1u);
  EXPECT_EQ(n.texcoords, 2u);
  EXPECT_EQ(n.triangles, 1u + 2u + 4u + 1u);
}

}  // namespace
}  // namespace tessera
