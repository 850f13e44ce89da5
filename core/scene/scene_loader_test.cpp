// Scene loader tests: every error names the scene file and the JSON path of the offending value; unknown keys warn
// (or fail under strict); assets stay inside the scene's folder unless an asset root is given; unsupported
// integrators and materials are refused with the list of supported ones; unreferenced textures are never read.
#include "core/scene/scene_loader.h"

#include "core/scene/checked_files.h"
#include "core/util/enum_names.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <string>

namespace tessera {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

class SceneLoader : public testing::TempDirTest {
 protected:
  // Loads `scene` written as scene.json and returns the SceneError message ("" when it loads).
  std::string error_of(const json& scene, const LoadOptions& opt = {}) {
    const fs::path p = write_scene("scene.json", scene);
    try {
      load_scene_file(p, opt);
    } catch (const SceneError& e) {
      return e.what();
    }
    return "";
  }
  // Expects loading to fail with a message that names the scene file and contains every string in `parts`.
  void expect_error(const json& scene, std::initializer_list<std::string> parts, const LoadOptions& opt = {}) {
    const std::string msg = error_of(scene, opt);
    ASSERT_FALSE(msg.empty()) << "the scene loaded";
    EXPECT_NE(msg.find(file("scene.json").string()), std::string::npos) << msg;
    for (const auto& part : parts) EXPECT_NE(msg.find(part), std::string::npos) << "'" << part << "' not in: " << msg;
  }
  json mesh_scene(const std::string& path) {
    json s = testing::minimal_scene();
    s["objects"].push_back({{"type", "mesh"}, {"path", path}, {"material_name", "white_diffuse"}});
    return s;
  }
  // The minimal scene with its material textured by tex/ok.exr (a 4x2 image, written too).
  json image_textured_scene() {
    Image img = Image::make(4, 2);
    img.set(1, 0, Vec3(0.5f));
    write_image("tex/ok.exr", img);
    json s = testing::minimal_scene();
    s["textures"]["img"] = {{"type", "image"}, {"path", "tex/ok.exr"}};
    s["materials"]["white_diffuse"]["texture_name"] = "img";
    return s;
  }
  // Overwrites `f` in place with as many bytes that do not decode (same file, same size).
  void spoil_in_place(const fs::path& f) {
    const auto size = fs::file_size(f);
    { std::ofstream(f, std::ios::binary | std::ios::in | std::ios::out) << std::string(size, 'x'); }
    ASSERT_EQ(fs::file_size(f), size);
  }
  // Replaces `f` as a store would (temp file, rename) with as many bytes that do not decode: another file.
  void replace_with_garbage(const fs::path& f) {
    write("tex/new.bin", std::string(fs::file_size(f), 'y'));
    fs::rename(file("tex/new.bin"), f);
  }
};

TEST_F(SceneLoader, MinimalSceneLoads) {
  const LoadedScene l = load_scene_file(write_scene("scene.json", testing::minimal_scene()));
  EXPECT_EQ(l.scene.width, 4);
  EXPECT_EQ(l.scene.height, 3);
  EXPECT_EQ(l.scene.spheres.size(), 1u);
  EXPECT_TRUE(l.warnings.empty());
  EXPECT_EQ(l.scene.hash.size(), 64u);
}

TEST_F(SceneLoader, MissingMeshFileNamesFileAndJsonPath) {
  expect_error(mesh_scene("meshes/nothere.obj"), {"objects[1].path", "nothere.obj", "not found"});
}

TEST_F(SceneLoader, MissingSceneFileIsAnError) {
  EXPECT_THROW(load_scene_file(file("absent.json")), SceneError);
}

TEST_F(SceneLoader, ObjWithPolygonFacesIsTriangulated) {
  write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  const LoadedScene l = load_scene_file(write_scene("scene.json", mesh_scene("quad.obj")));
  EXPECT_EQ(l.scene.triangles.size(), 2u);
}

TEST_F(SceneLoader, CheckingWithoutBuildingGivesTheSameSceneWithoutItsBvh) {
  // A submission is checked with build = false: the same hash, size, settings, warnings and assets, no BVH.
  write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 1 1 2\n");
  const fs::path p = write_scene("scene.json", mesh_scene("quad.obj"));
  const LoadedScene built = load_scene_file(p);
  LoadOptions check;
  check.build = false;
  const LoadedScene checked = load_scene_file(p, check);
  EXPECT_EQ(checked.scene.hash, built.scene.hash);
  EXPECT_EQ(checked.scene.width, built.scene.width);
  EXPECT_EQ(checked.scene.settings.spp, built.scene.settings.spp);
  EXPECT_EQ(checked.scene.triangles.size(), built.scene.triangles.size());
  EXPECT_EQ(checked.warnings, built.warnings);
  ASSERT_EQ(checked.warnings.size(), 1u);  // the zero-area face
  EXPECT_EQ(checked.assets, built.assets);
  EXPECT_EQ(built.scene.bvh.triangle_count(), 2u);
  EXPECT_EQ(checked.scene.bvh.triangle_count(), 0u);
}

TEST_F(SceneLoader, BadObjVertexIndexNamesJsonPath) {
  write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  expect_error(mesh_scene("bad.obj"), {"objects[1].path", "bad.obj", "vertex 7"});
}

TEST_F(SceneLoader, BinaryObjIsAnErrorNotAnEmptyMesh) {
  write("binary.obj", std::string("v/1\x01\x02\0\0\0channels\0", 18));
  expect_error(mesh_scene("binary.obj"), {"objects[1].path", "not a valid OBJ: binary data (a NUL byte at offset 5)"});
}

TEST_F(SceneLoader, DeeplyNestedJsonIsRefusedBeforeParsing) {
  EXPECT_EQ(json_nesting_depth(R"({"a": [1, {"b": "[[[{{{"}], "c\"[": []})"), 3);
  const std::string deep = R"({"objects": )" + std::string(100000, '[') + std::string(100000, ']') + "}";
  try {
    load_scene_text(deep, "deep.json", [](const std::string&, const std::string&) { return fs::path(); });
    FAIL() << "a scene nested 100001 levels deep loaded";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("deep.json: invalid JSON: arrays/objects nested deeper than 64 levels"),
              std::string::npos) << e.what();
  }
}

TEST_F(SceneLoader, BadObjNormalIndexNamesJsonPath) {
  write("badn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//5\n");
  expect_error(mesh_scene("badn.obj"), {"objects[1].path", "badn.obj", "normal 5"});
}

TEST_F(SceneLoader, UnreadableExrNamesTextureAndJsonPath) {
  write("tex/broken.exr", "this is not an OpenEXR file");
  json s = testing::minimal_scene();
  s["textures"]["img"] = {{"type", "image"}, {"path", "tex/broken.exr"}};
  s["materials"]["white_diffuse"]["texture_name"] = "img";
  expect_error(s, {"textures.img.path", "broken.exr"});
}

TEST_F(SceneLoader, ReadableExrTextureLoads) {
  Image img = Image::make(2, 2);
  img.set(1, 0, Vec3(0.5f));
  write_image("tex/ok.exr", img);
  json s = testing::minimal_scene();
  s["textures"]["img"] = {{"type", "image"}, {"path", "tex/ok.exr"},
                          {"tex_coordinate_generator", {{"type", "uvmapping2d"}, {"scale", {2, 2}}, {"delta", {0.5, 0}}}}};
  s["materials"]["white_diffuse"]["texture_name"] = "img";
  const LoadedScene l = load_scene_file(write_scene("scene.json", s));
  ASSERT_EQ(l.scene.textures.size(), 1u);
  ASSERT_NE(l.scene.textures[0].image, nullptr);
  EXPECT_EQ(l.scene.textures[0].scale, Vec2(2.f));
  EXPECT_EQ(l.scene.textures[0].delta, Vec2(0.5f, 0.f));
  EXPECT_EQ(l.assets, (std::vector<std::string>{"tex/ok.exr"}));
}

// A check (no build) with a CheckedFiles record decodes an image once: the next check takes its digest from the
// record (the file is overwritten in place below with as many bytes that do not decode, to show it was not read),
// while a load that builds, a check without the record, or a check after the file was replaced reads it and fails.
TEST_F(SceneLoader, ChecksWithARecordDecodeEachUnchangedImageOnce) {
  const json s = image_textured_scene();
  const fs::path tex = file("tex/ok.exr");
  const fs::path scene = write_scene("scene.json", s);
  CheckedFiles record;
  LoadOptions check;
  check.build = false;
  check.checked_files = &record;
  const LoadedScene first = load_scene_file(scene, check);
  ASSERT_NE(first.scene.textures[0].image, nullptr);
  EXPECT_EQ(record.size(), 1u);
  EXPECT_EQ(first.scene.hash, load_scene_file(scene).scene.hash);

  spoil_in_place(tex);
  const LoadedScene second = load_scene_file(scene, check);
  EXPECT_EQ(second.scene.textures[0].image, nullptr);  // not decoded
  EXPECT_EQ(second.scene.hash, first.scene.hash);
  EXPECT_NE(error_of(s).find("textures.img.path"), std::string::npos);  // a build reads it
  LoadOptions unrecorded;
  unrecorded.build = false;
  EXPECT_NE(error_of(s, unrecorded).find("textures.img.path"), std::string::npos);
  LoadOptions build_with_record;  // the record has no pixels to give
  build_with_record.checked_files = &record;
  EXPECT_NE(error_of(s, build_with_record).find("textures.img.path"), std::string::npos);

  replace_with_garbage(tex);  // another file now: read again
  EXPECT_NE(error_of(s, check).find("textures.img.path"), std::string::npos);
}

// A build with a record that keeps pixels (a farm worker's, across jobs) decodes each unchanged image once: the next
// build takes the same pixels from the record (the file is overwritten in place with bytes that do not decode, to
// show it was not read); a build without pixel budget, or after the file was replaced, reads it and fails.
TEST_F(SceneLoader, BuildsWithARecordKeepingPixelsDecodeEachUnchangedImageOnce) {
  const json s = image_textured_scene();
  const fs::path tex = file("tex/ok.exr");
  const fs::path scene = write_scene("scene.json", s);
  CheckedFiles record(16, size_t(1) << 20);
  LoadOptions build;
  build.checked_files = &record;
  const LoadedScene first = load_scene_file(scene, build);
  ASSERT_NE(first.scene.textures[0].image, nullptr);
  EXPECT_EQ(record.image_bytes(), 4u * 2u * 3u * sizeof(float));

  spoil_in_place(tex);
  const LoadedScene second = load_scene_file(scene, build);
  EXPECT_EQ(first.images_reused, 0);
  EXPECT_EQ(second.images_reused, 1);
  EXPECT_EQ(second.scene.textures[0].image, first.scene.textures[0].image);  // the same pixels, not decoded again
  EXPECT_EQ(second.scene.hash, first.scene.hash);
  CheckedFiles digests_only;
  digests_only.remember(tex, "any");
  LoadOptions without_pixels;
  without_pixels.checked_files = &digests_only;
  EXPECT_NE(error_of(s, without_pixels).find("textures.img.path"), std::string::npos);

  replace_with_garbage(tex);  // another file now: read again
  EXPECT_NE(error_of(s, build).find("textures.img.path"), std::string::npos);
}

// The environment map's sampling table depends on its pixels alone: a build that takes recorded pixels takes the table
// built from them too (the same object), and the scene is the same; without a record, or with a record too small for
// the table, it is built again.
TEST_F(SceneLoader, BuildsWithARecordKeepTheEnvironmentsSamplingTable) {
  Image sky = Image::make(16, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) sky.set(x, y, Vec3(0.1f * float(x + 1), 0.05f * float(y + 1), 0.3f));
  write_image("tex/sky.exr", sky);
  json s = testing::minimal_scene();
  s["textures"]["sky"] = {{"type", "image"}, {"path", "tex/sky.exr"}};
  s["environment_map"] = {{"texture_name", "sky"}, {"scale", 2}};
  const fs::path scene = write_scene("scene.json", s);
  CheckedFiles record(16, size_t(1) << 20);
  LoadOptions build;
  build.checked_files = &record;
  const LoadedScene first = load_scene_file(scene, build);
  ASSERT_TRUE(first.scene.environment);
  EXPECT_FALSE(first.environment_reused);
  ASSERT_NE(first.scene.environment->dist, nullptr);
  EXPECT_EQ(record.find(file("tex/sky.exr"))->environment, first.scene.environment->dist);
  const LoadedScene second = load_scene_file(scene, build);
  EXPECT_TRUE(second.environment_reused);
  EXPECT_EQ(second.scene.environment->dist, first.scene.environment->dist);
  EXPECT_EQ(second.scene.hash, first.scene.hash);
  // The same samples and densities as a table built afresh.
  const LoadedScene fresh = load_scene_file(scene);
  EXPECT_NE(fresh.scene.environment->dist, first.scene.environment->dist);
  for (float u : {0.1f, 0.37f, 0.5f, 0.93f}) {
    const LightSample a = second.scene.environment->sample(Vec2(u, 1.f - u));
    const LightSample b = fresh.scene.environment->sample(Vec2(u, 1.f - u));
    EXPECT_EQ(a.p, b.p);
    EXPECT_EQ(a.pdf, b.pdf);
    EXPECT_EQ(second.scene.environment->pdf(a.p), fresh.scene.environment->pdf(a.p));
  }
  CheckedFiles pixels_only(16, 16 * 8 * 12);  // room for the pixels, not the table
  build.checked_files = &pixels_only;
  load_scene_file(scene, build);
  const LoadedScene without_table = load_scene_file(scene, build);
  EXPECT_EQ(without_table.images_reused, 1);
  EXPECT_FALSE(without_table.environment_reused);
}

TEST_F(SceneLoader, UnreferencedTexturesAreNeverRead) {
  json s = testing::minimal_scene();
  s["textures"]["unused"] = {{"type", "image"}, {"path", "does/not/exist.exr"}};
  const LoadedScene l = load_scene_file(write_scene("scene.json", s));
  EXPECT_TRUE(l.assets.empty());
  EXPECT_EQ(l.scene.textures.size(), 1u);
  EXPECT_EQ(scene_asset_paths(s), std::vector<std::string>{});
  // Referencing it makes it an error, naming its JSON path.
  s["materials"]["white_diffuse"]["texture_name"] = "unused";
  expect_error(s, {"textures.unused.path", "exist.exr"});
}

TEST_F(SceneLoader, NanSizeNamesJsonPath) {
  // JSON text cannot hold NaN; a parsed document built in memory can.
  json s = testing::minimal_scene();
  s["objects"][0]["radius"] = std::numeric_limits<double>::quiet_NaN();
  try {
    load_scene_json(s, "mem.json", [](const std::string& p, const std::string&) { return fs::path(p); });
    FAIL() << "NaN radius accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("mem.json: objects[0].radius"), std::string::npos) << e.what();
  }
}

TEST_F(SceneLoader, NumberOverflowingDoubleIsASceneError) {
  // The JSON parser itself refuses 1e999 (it names the byte offset, not a JSON path); it must still be a SceneError.
  std::string text = testing::minimal_scene().dump();
  const std::string key = "\"radius\":1";
  text.replace(text.find(key), key.size(), "\"radius\":1e999");
  write("scene.json", text);
  try {
    load_scene_file(file("scene.json"));
    FAIL() << "1e999 accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find(file("scene.json").string()), std::string::npos) << e.what();
  }
}

TEST_F(SceneLoader, FloatOverflowingNumbersNameJsonPath) {
  // 1e39 is finite as a double but overflows a float.
  for (const char* v : {"1e39", "-1e39"}) {
    std::string text = testing::minimal_scene().dump();
    const std::string key = "\"radius\":1";
    text.replace(text.find(key), key.size(), std::string("\"radius\":") + v);
    write("scene.json", text);
    try {
      load_scene_file(file("scene.json"));
      ADD_FAILURE() << "radius " << v << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("objects[0].radius"), std::string::npos) << e.what();
    }
  }
  json s = testing::minimal_scene();
  s["integrator"]["point_light_flux"] = {1e39, 1, 1};
  expect_error(s, {"integrator.point_light_flux[0]"});
}

TEST_F(SceneLoader, NegativeSizesNameJsonPath) {
  json s = testing::minimal_scene();
  s["objects"][0]["radius"] = -0.5;
  expect_error(s, {"objects[0].radius", "negative"});
  s = testing::minimal_scene();
  s["film"]["resolution"] = {-4, 3};
  expect_error(s, {"film.resolution[0]"});
  s = testing::minimal_scene();
  s["textures"]["white"]["color"] = {1, -1, 1};
  expect_error(s, {"textures.white.color"});
}

TEST_F(SceneLoader, ZeroResolutionNamesJsonPath) {
  json s = testing::minimal_scene();
  s["film"]["resolution"] = {4, 0};
  expect_error(s, {"film.resolution[1]"});
}

TEST_F(SceneLoader, UnknownKeysWarnAndStrictMakesThemErrors) {
  json s = testing::minimal_scene();
  s["objects"][0]["colour"] = "red";
  s["camera"]["aperture"] = 0.1;
  const LoadedScene l = load_scene_file(write_scene("scene.json", s));
  ASSERT_EQ(l.warnings.size(), 2u);
  std::string all = l.warnings[0] + "\n" + l.warnings[1];
  EXPECT_NE(all.find("objects[0].colour"), std::string::npos) << all;
  EXPECT_NE(all.find("camera.aperture"), std::string::npos) << all;
  LoadOptions strict;
  strict.strict = true;
  expect_error(s, {"camera.aperture", "unknown key"}, strict);
}

TEST_F(SceneLoader, UnknownKeysInUnusedTexturesAndMaterialsWarnToo) {
  json s = testing::minimal_scene();
  s["textures"]["spare"] = {{"type", "image"}, {"path", "never/read.exr"}, {"scael", {1, 1}}};
  s["materials"]["spare"] = {{"type", "refraction"}, {"etta", 1.3}};
  const LoadedScene l = load_scene_file(write_scene("scene.json", s));
  ASSERT_EQ(l.warnings.size(), 2u);
  const std::string all = l.warnings[0] + "\n" + l.warnings[1];
  EXPECT_NE(all.find("textures.spare.scael"), std::string::npos) << all;
  EXPECT_NE(all.find("materials.spare.etta"), std::string::npos) << all;
}

TEST_F(SceneLoader, TypeMismatchesAreSceneErrors) {
  for (const char* bad : {R"({"objects": {}})", R"({"objects": [{"type": 5}]})", R"({"objects": [{"type": "sphere", "radius": "big", "material_name": "m"}]})",
                          R"({"film": {"resolution": [4]}, "objects": []})", R"({"camera": {"fov": [1]}, "objects": []})", R"([1, 2])"}) {
    write("scene.json", bad);
    EXPECT_THROW(load_scene_file(file("scene.json")), SceneError) << bad;
    EXPECT_NO_THROW(scene_asset_paths(json::parse(bad))) << bad;
  }
}

TEST_F(SceneLoader, StrategyNamesRoundTripAndMisspellingsListTheChoices) {
  // Every name in the tables (the CLI offers the same ones) loads as its own enumerator...
  for (size_t i = 0; i < std::size(kAreaSamplingNames); ++i)
    for (size_t j = 0; j < std::size(kEnvSamplingNames); ++j) {
      json s = testing::minimal_scene();
      s["integrator"]["area_sampling"] = kAreaSamplingNames[i];
      s["integrator"]["env_sampling"] = kEnvSamplingNames[j];
      const LoadedScene l = load_scene_file(write_scene("scene.json", s), {});
      EXPECT_EQ(enum_name(l.scene.settings.area_sampling, kAreaSamplingNames), kAreaSamplingNames[i]);
      EXPECT_EQ(enum_name(l.scene.settings.env_sampling, kEnvSamplingNames), kEnvSamplingNames[j]);
    }
  // ...absent keys give the defaults...
  const LoadedScene d = load_scene_file(write_scene("scene.json", testing::minimal_scene()), {});
  EXPECT_EQ(d.scene.settings.area_sampling, AreaSampling::kAuto);
  EXPECT_EQ(d.scene.settings.env_sampling, EnvSampling::kMis);
  // ...and a misspelling or a wrong type is an error naming the key and the valid names.
  for (const char* key : {"area_sampling", "env_sampling", "bvh"}) {
    json s = testing::minimal_scene();
    s["integrator"][key] = "solid-angle";
    const std::string choices = std::string(key) == "bvh" ? "sah, median"
                                : std::string(key) == "area_sampling" ? "auto, solid_angle, area"
                                                                      : "mis, importance, cosine, uniform";
    expect_error(s, {std::string("integrator.") + key, "'solid-angle' is not one of: " + choices});
    s["integrator"][key] = 1;
    expect_error(s, {std::string("integrator.") + key, "expected a string"});
  }
  EXPECT_EQ(enum_from_name<SplitMethod>("median", kSplitMethodNames), SplitMethod::kMedian);
  EXPECT_FALSE(enum_from_name<SplitMethod>("Median", kSplitMethodNames).has_value());
}

TEST_F(SceneLoader, AssetPathsMustStayInsideTheSceneFolder) {
  write("outside.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  // The scene lives one level down; "../outside.obj" escapes its folder.
  json s = mesh_scene("../outside.obj");
  write_scene("sub/scene.json", s);
  try {
    load_scene_file(file("sub/scene.json"));
    FAIL() << "escaping path accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("objects[1].path"), std::string::npos) << e.what();
  }
  // The same with an explicit asset root above both loads.
  LoadOptions opt;
  opt.asset_root = dir_;
  EXPECT_EQ(load_scene_file(file("sub/scene.json"), opt).scene.triangles.size(), 1u);
  opt.asset_root = fs::path(dir_.string() + "/");  // a trailing separator changes nothing
  EXPECT_EQ(load_scene_file(file("sub/scene.json"), opt).scene.triangles.size(), 1u);
  // Escaping through a folder that exists and back out is still caught.
  write("sub/inner/keep.txt", "");
  write_scene("sub/scene.json", mesh_scene("inner/../../outside.obj"));
  EXPECT_THROW(load_scene_file(file("sub/scene.json")), SceneError);
}

TEST_F(SceneLoader, AbsoluteAssetPathsNeedAnAssetRoot) {
  const fs::path obj = write("abs.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_scene("sub/scene.json", mesh_scene(obj.string()));
  try {
    load_scene_file(file("sub/scene.json"));
    FAIL() << "absolute path accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("objects[1].path"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("absolute"), std::string::npos) << e.what();
  }
  LoadOptions opt;
  opt.asset_root = dir_;
  EXPECT_EQ(load_scene_file(file("sub/scene.json"), opt).scene.triangles.size(), 1u);
  // An absolute path outside the asset root stays an error.
  opt.asset_root = dir_ / "sub";
  EXPECT_THROW(load_scene_file(file("sub/scene.json"), opt), SceneError);
}

TEST_F(SceneLoader, PathAndBdptSelectThePathTracerUnlessForcedDirect) {
  for (const char* type : {"path", "bdpt"}) {
    json s = testing::minimal_scene();
    s["integrator"]["type"] = type;
    s["integrator"]["rr_threshold"] = 0.25;
    s["integrator"]["profile"] = "NextEventEstimation";
    const LoadedScene p = load_scene_file(write_scene("scene.json", s));
    EXPECT_EQ(p.scene.settings.integrator, IntegratorKind::kPath);
    EXPECT_EQ(p.scene.settings.profile, PathProfile::kNee);
    EXPECT_FLOAT_EQ(p.scene.settings.rr_threshold, 0.25f);
    EXPECT_TRUE(p.warnings.empty());
    EXPECT_EQ(p.notes.size(), std::string(type) == "bdpt" ? 1u : 0u);  // bdpt says it renders with the path tracer
    LoadOptions direct;
    direct.force_direct = true;
    const LoadedScene l = load_scene_file(write_scene("scene.json", s), direct);
    EXPECT_EQ(l.scene.settings.integrator, IntegratorKind::kDirect);
    EXPECT_FALSE(l.notes.empty());
  }
  json s = testing::minimal_scene();
  s["integrator"]["type"] = "photon";
  expect_error(s, {"integrator.type", "photon", "intersection_test, direct, path, bdpt", "--integrator direct"});
  s["integrator"]["type"] = "path";
  s["integrator"]["profile"] = "MLT";
  expect_error(s, {"integrator.profile", "MLT", "RandomWalk"});
  for (const char* p : {"MIS", "MultipleImportanceSampling", "NEE", "RW", "RandomWalk"}) {
    s["integrator"]["profile"] = p;
    EXPECT_EQ(error_of(s), "") << p;
  }
}

TEST_F(SceneLoader, GlassRoughConductorAndCheckerboardLoadForThePathTracer) {
  json s = testing::minimal_scene();
  s["integrator"]["type"] = "path";
  s["textures"]["checks"] = {{"type", "checkerboard"}, {"color0", {1, 0, 0}}, {"color1", {0, 0, 1}},
                             {"tex_coordinate_generator", {{"type", "uvmapping2d"}, {"scale", {2, 2}}}}};
  s["materials"]["metal"] = {{"type", "roughconductor"}, {"alpha_x", 0.05}, {"alpha_y", 0.2},
                             {"etaT", {0.2, 0.9, 1.1}}, {"k", {3.9, 2.4, 2.2}}, {"texture_name", "checks"}};
  s["materials"]["glass"] = {{"type", "glass"}, {"eta", 1.8}, {"T", {0.9, 1, 1}}};
  s["objects"].push_back({{"type", "sphere"}, {"center", {2, 0, 0}}, {"material_name", "metal"}});
  s["objects"].push_back({{"type", "sphere"}, {"center", {-2, 0, 0}}, {"material_name", "glass"}});
  const LoadedScene l = load_scene_file(write_scene("scene.json", s));
  EXPECT_TRUE(l.warnings.empty());
  const Material& metal = l.scene.materials[l.scene.sphere_attr[1].material];
  EXPECT_EQ(metal.kind, MaterialKind::kRoughConductor);
  EXPECT_FLOAT_EQ(metal.alpha_y, 0.2f);
  EXPECT_FLOAT_EQ(metal.eta_t.y, 0.9f);
  const Texture& checks = l.scene.textures[metal.texture];
  EXPECT_TRUE(checks.checkerboard);
  const Material& glass = l.scene.materials[l.scene.sphere_attr[2].material];
  EXPECT_EQ(glass.kind, MaterialKind::kGlass);
  EXPECT_FLOAT_EQ(glass.eta, 1.8f);
  EXPECT_FLOAT_EQ(glass.transmit_tint.x, 0.9f);
  // The direct integrator cannot render them.
  LoadOptions direct;
  direct.force_direct = true;
  expect_error(s, {"materials.metal.type", "roughconductor", "path integrator"}, direct);
  s["materials"]["metal"]["alpha_x"] = 0;
  expect_error(s, {"materials.metal.alpha_x"});
}

TEST_F(SceneLoader, OtherMaterialsAreRefused) {
  for (const char* type : {"microfacet", "dielectric"}) {
    json s = testing::minimal_scene();
    s["materials"]["white_diffuse"] = {{"type", type}, {"texture_name", "white"}};
    expect_error(s, {"materials.white_diffuse.type", type, "diffuse, refraction, glass, roughconductor"});
    s["integrator"]["type"] = "path";
    expect_error(s, {"materials.white_diffuse.type", type, "diffuse, refraction, glass, roughconductor"});
  }
}

TEST_F(SceneLoader, RectangleEmitterBecomesASphericalRectangleLight) {
  write("light.obj", testing::rect_obj(Vec3(-0.5f, 1.f, -0.5f), Vec3(1.f, 0.f, 0.f), Vec3(0.f, 0.f, 1.f)));
  json s = testing::minimal_scene();
  s["objects"].push_back({{"type", "mesh"}, {"path", "light.obj"}, {"light", {{"type", "area"}, {"radiance", {2, 2, 2}}}}});
  const LoadedScene l = load_scene_file(write_scene("scene.json", s));
  ASSERT_EQ(l.scene.area_lights.size(), 1u);
  const AreaLight& a = l.scene.area_lights[0];
  EXPECT_EQ(a.rects.size(), 1u);
  EXPECT_TRUE(a.tris.empty());
  EXPECT_NEAR(a.total_area, 1.f, 1e-6f);
  EXPECT_NEAR(a.rects[0].n.y, -1.f, 1e-6f);  // cross(x, z) = -y: the winding faces down
}

TEST_F(SceneLoader, CourseScenesLoad) {
  for (const char* name : {"sphere.json", "glass_sphere.json"}) {
    const LoadedScene l = load_scene_file(fs::path(TESSERA_COURSE_DIR) / name);
    EXPECT_EQ(l.scene.settings.integrator, IntegratorKind::kPath) << name;
    EXPECT_EQ(l.scene.settings.max_depth, 64) << name;
    EXPECT_TRUE(l.warnings.empty()) << name;
  }
  for (const char* name : {"cbox.json", "cbox_no_light.json", "cbox_no_light_refract.json", "cbox_refract_textured.json"}) {
    LoadOptions opt;
    opt.force_direct = true;
    const LoadedScene l = load_scene_file(fs::path(TESSERA_COURSE_DIR) / name, opt);
    EXPECT_GT(l.scene.triangles.size(), 0u) << name;
    if (std::string(name) == "cbox_refract_textured.json") {
      // This user's scene lists two floors in the same place (objects[0] textured, objects[3] grey): exactly one
      // warning, naming both objects.
      ASSERT_EQ(l.warnings.size(), 1u) << name;
      EXPECT_NE(l.warnings[0].find("objects[3]"), std::string::npos) << l.warnings[0];
      EXPECT_NE(l.warnings[0].find("coincide exactly with triangles of objects[0]"), std::string::npos) << l.warnings[0];
    } else {
      EXPECT_TRUE(l.warnings.empty()) << name << ": " << (l.warnings.empty() ? "" : l.warnings[0]);
    }
  }
}

}  // namespace
}  // namespace tessera
