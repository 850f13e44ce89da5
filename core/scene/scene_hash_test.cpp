// The scene hash (LoadedScene::scene.hash, written as tessera:sceneHash and used by the farm to name a job's
// scene): SHA-256 over the scene's JSON content and the bytes of every asset it uses. Any change to the JSON's
// content or to one byte of a used mesh or texture changes it; reformatting the JSON or touching a texture no
// material uses does not.
#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

namespace tessera {
namespace {

class SceneHash : public testing::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    write("mesh.obj", testing::rect_obj(Vec3(-1, -1, -2), Vec3(2, 0, 0), Vec3(0, 2, 0), true));
    Image tex = Image::make(4, 4);
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) tex.set(x, y, Vec3(0.1f * float(x), 0.2f * float(y), 0.5f));
    write_image("tex.exr", tex);
    write_image("unused.exr", tex);
    scene_ = testing::minimal_scene();
    scene_["textures"]["checker"] = {{"type", "image"}, {"path", "tex.exr"}};
    scene_["textures"]["unused"] = {{"type", "image"}, {"path", "unused.exr"}};
    scene_["materials"]["textured"] = {{"type", "diffuse"}, {"texture_name", "checker"}};
    scene_["objects"].push_back({{"type", "mesh"}, {"path", "mesh.obj"}, {"material_name", "textured"}});
  }
  std::string hash_of(const nlohmann::json& scene, int indent = 2) {
    write("scene.json", scene.dump(indent));
    return load_scene_file(file("scene.json")).scene.hash;
  }
  std::string hash() { return hash_of(scene_); }
  std::string bytes(const std::string& name) const {
    std::ifstream in(file(name), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  void put(const std::string& name, const std::string& b) const { std::ofstream(file(name), std::ios::binary) << b; }

  nlohmann::json scene_;
};

TEST_F(SceneHash, IsTheSameForTheSameContentWhateverTheFormatting) {
  const std::string h = hash();
  EXPECT_EQ(64u, h.size());
  EXPECT_EQ(h, hash());
  EXPECT_EQ(h, hash_of(scene_, -1));  // one line instead of indented
}

TEST_F(SceneHash, ChangesWithAnyValueOfTheJson) {
  const std::string h = hash();
  for (const auto& [pointer, value] : std::vector<std::pair<std::string, nlohmann::json>>{
           {"/camera/fov", 45.5},
           {"/film/resolution/0", 5},
           {"/integrator/spp", 2},
           {"/textures/white/color/1", 0.999},
           {"/objects/0/radius", 1.0000001},
           {"/textures/unused/path", "tex.exr"}}) {
    nlohmann::json changed = scene_;
    changed[nlohmann::json::json_pointer(pointer)] = value;
    EXPECT_NE(h, hash_of(changed)) << pointer;
  }
}

// Every byte of a used asset counts: a changed digit of the mesh, a byte appended to it (the same triangles), one
// texel's float changed in its last bit, and a byte appended after the texture's EXR data (the same texels).
TEST_F(SceneHash, ChangesWithAnyByteOfAUsedMeshOrTexture) {
  const std::string h = hash();
  const std::string mesh = bytes("mesh.obj"), tex = bytes("tex.exr");

  std::string digit = mesh;
  const size_t at = digit.find_last_of("0123456789", digit.find("vt"));
  ASSERT_NE(std::string::npos, at);
  digit[at] = digit[at] == '1' ? '2' : '1';
  put("mesh.obj", digit);
  EXPECT_NE(h, hash()) << "a vertex digit";
  put("mesh.obj", mesh + " ");
  EXPECT_NE(h, hash()) << "a byte appended to the mesh";
  put("mesh.obj", mesh);
  EXPECT_EQ(h, hash());

  Image img = read_exr(file("tex.exr")).pixels;
  img.rgb[7] = std::nextafter(img.rgb[7], 1.f);
  write_image("tex.exr", img);
  EXPECT_NE(h, hash()) << "one texel's last bit";
  put("tex.exr", tex + '\0');
  EXPECT_NE(h, hash()) << "a byte appended to the texture";
  put("tex.exr", tex);
  EXPECT_EQ(h, hash());
}

// README: the loader reads only textures that a used material or the environment refers to, and the hash covers the
// assets the scene uses; a texture listed but used by no material is neither read nor hashed.
TEST_F(SceneHash, IgnoresATextureNoMaterialUses) {
  const std::string h = hash();
  put("unused.exr", bytes("unused.exr") + "x");
  EXPECT_EQ(h, hash());
  std::filesystem::remove(file("unused.exr"));
  EXPECT_EQ(h, hash());
}

}  // namespace
}  // namespace tessera
