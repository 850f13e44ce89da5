// Output layers against closed forms (the depth of a plane square to the view, the normal of a sphere, the albedo
// of a constant texture, ids through refraction), and their invariance: any tile size, window split and thread count
// gives the same bits, the colour is bitwise the same with layers as without, and a continued render equals an
// uninterrupted one in every layer.
#include "core/render/layer_film.h"

#include "core/image/cryptomatte.h"
#include "core/render/render.h"
#include "core/render/render_state.h"
#include "core/scene/scene_loader.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

namespace tessera {
namespace {

namespace fs = std::filesystem;

LoadedScene layer_scene(const std::string& json) {
  return load_scene_text(json, "layers", [](const std::string& p, const std::string&) { return fs::path(p); });
}

// A camera looking down -z from (0, 0, 4) (the scene file's coordinates) at a wall square to the view at z = -2,
// (6 from the eye), filling the view, and a sphere of radius 1 at the origin in front of it.
const char* const kWallAndSphere = R"({
  "integrator": {"type": "intersection_test", "spp": 4, "point_light_position": [0, 3, 4]},
  "film": {"resolution": [40, 30]},
  "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov": 40},
  "textures": {"t": {"type": "constant", "color": [0.3, 0.55, 0.7]}, "g": {"type": "constant", "color": [0.5, 0.5, 0.5]}},
  "materials": {"wall": {"type": "diffuse", "texture_name": "t"}, "ball": {"type": "diffuse", "texture_name": "g"}},
  "objects": [
    {"type": "sphere", "name": "ball", "center": [0, 0, 0], "radius": 1, "material_name": "ball"},
    {"type": "sphere", "name": "wall", "center": [0, 0, -100002], "radius": 100000, "material_name": "wall"}
  ]
})";

RenderResult render_layers(const Scene& scene, LayerSet layers, uint32_t spp, int tile = 16, PixelWindow window = {}) {
  RenderOptions o;
  o.spp = spp;
  o.seed = 3;
  o.layers = layers;
  o.tile_size = tile;
  o.window = window;
  return render(scene, o);
}

const LayerSet kAll = LayerSet::from_bits(~0u);

// kWallAndSphere without its ball.
std::string wall_only() {
  std::string json = kWallAndSphere;
  const std::string ball = R"(
    {"type": "sphere", "name": "ball", "center": [0, 0, 0], "radius": 1, "material_name": "ball"},)";
  json.erase(json.find(ball), ball.size());
  return json;
}

TEST(LayerFilm, DepthOfAPlaneSquareToTheViewIsItsDistance) {
  // A sphere of radius 1e5 is flat to within 3e-5 over the view's width: Z is 6 at every pixel, P.Z is -2.
  const LoadedScene l = layer_scene(wall_only());
  const RenderResult r = render_layers(l.scene, parse_layers("depth,position"), 8);
  const std::vector<float>& z = r.image.extra.at("Z");
  const std::vector<float>& pz = r.image.extra.at("P.Z");
  for (size_t i = 0; i < z.size(); ++i) {
    EXPECT_NEAR(z[i], 6.f, 1e-4f) << i;
    EXPECT_NEAR(pz[i], -2.f, 1e-4f) << i;
  }
}

TEST(LayerFilm, NormalOfASphereIsItsRadialDirection) {
  // One sample per pixel: N and P describe the same point, so N = P - centre for the unit ball at the origin.
  const LoadedScene l = layer_scene(kWallAndSphere);
  const RenderResult r = render_layers(l.scene, parse_layers("normal,position,object_id"), 1);
  const auto& e = r.image.extra;
  int ball = 0;
  for (size_t i = 0; i < e.at("N.X").size(); ++i) {
    if (e.at("object_id")[i] != 1.f) continue;
    ++ball;
    const Vec3 n(e.at("N.X")[i], e.at("N.Y")[i], e.at("N.Z")[i]), p(e.at("P.X")[i], e.at("P.Y")[i], e.at("P.Z")[i]);
    EXPECT_NEAR(glm::length(n), 1.f, 1e-5f);
    EXPECT_NEAR(glm::length(p), 1.f, 1e-5f);
    EXPECT_NEAR(glm::length(n - p), 0.f, 2e-5f) << i;
    EXPECT_GT(n.z, 0.f) << "the normal faces the camera";
  }
  EXPECT_GT(ball, 100);
}

TEST(LayerFilm, AlbedoOfAConstantTextureIsExact) {
  // Every pixel whose samples all reach the wall holds the wall's colour to the bit (a sum of n equal floats in
  // double, divided by n, is exact); the wall alone gives it everywhere.
  const LoadedScene l = layer_scene(kWallAndSphere);
  const RenderResult r = render_layers(l.scene, parse_layers("albedo,crypto_object"), 16);
  const auto& e = r.image.extra;
  const float wall = cryptomatte_float(cryptomatte_id("wall"));
  int full = 0;
  for (size_t i = 0; i < e.at("albedo.R").size(); ++i) {
    if (e.at("crypto_object00.G")[i] != 1.f || std::memcmp(&e.at("crypto_object00.R")[i], &wall, 4) != 0) continue;
    ++full;
    EXPECT_EQ(Vec3(e.at("albedo.R")[i], e.at("albedo.G")[i], e.at("albedo.B")[i]), Vec3(0.3f, 0.55f, 0.7f)) << i;
  }
  EXPECT_GT(full, 700);
  const LoadedScene w = layer_scene(wall_only());
  const RenderResult rw = render_layers(w.scene, parse_layers("albedo"), 16);
  for (const float v : rw.image.extra.at("albedo.G")) ASSERT_EQ(v, 0.55f);
}

TEST(LayerFilm, IdsAndCryptomatteAgreeAndCoverageSumsToOne) {
  const LoadedScene l = layer_scene(kWallAndSphere);
  const RenderResult r = render_layers(l.scene, kAll, 16);
  const auto& e = r.image.extra;
  const float wall = cryptomatte_float(cryptomatte_id("wall")), ball = cryptomatte_float(cryptomatte_id("ball"));
  for (size_t i = 0; i < e.at("material_id").size(); ++i) {
    double sum = 0;
    for (int g = 0; g < 3; ++g) {
      const std::string c = "crypto_material0" + std::to_string(g);
      sum += double(e.at(c + ".G")[i]) + double(e.at(c + ".A")[i]);
    }
    EXPECT_NEAR(sum, 1.0, 1e-6) << i;  // nothing is background here
    // material 1 is the ball (named first), 2 the wall; the first rank is the most covering one.
    const float first = e.at("crypto_material00.R")[i];
    const float mat = e.at("material_id")[i];
    if (e.at("crypto_material00.G")[i] > 0.5f) {
      EXPECT_EQ(first, mat == 1.f ? ball : wall) << i;
    }
    EXPECT_EQ(std::memcmp(&e.at("crypto_object00.R")[i], &first, 4), 0) << "objects are named like their materials";
  }
  const auto meta = layer_metadata(l.scene, kAll);
  ASSERT_EQ(meta.size(), 8u);
  for (const auto& [k, v] : meta) {
    if (k.find("/manifest") != std::string::npos) {
      EXPECT_NE(v.find("\"wall\""), std::string::npos) << v;
    }
  }
}

TEST(LayerFilm, RefractionShowsTheSurfaceBehind) {
  // A refracting ball before the wall: layers describe the wall seen through it (albedo, object), not the ball.
  std::string json = kWallAndSphere;
  json.replace(json.find(R"("ball": {"type": "diffuse", "texture_name": "g"})"),
               std::string(R"("ball": {"type": "diffuse", "texture_name": "g"})").size(),
               R"("ball": {"type": "refraction", "eta": 1.5})");
  const LoadedScene l = layer_scene(json);
  const RenderResult r = render_layers(l.scene, parse_layers("albedo,object_id,depth"), 4);
  const size_t centre = size_t(15) * 40 + 20;
  EXPECT_EQ(r.image.extra.at("object_id")[centre], 2.f);
  EXPECT_EQ(r.image.extra.at("albedo.R")[centre], 0.3f);
  EXPECT_GT(r.image.extra.at("Z")[centre], 5.f);
}

TEST(LayerFilm, BackgroundHasNoIdsAndInfiniteDepth) {
  std::string json = kWallAndSphere;
  const std::string wall = R"(,
    {"type": "sphere", "name": "wall", "center": [0, 0, -100002], "radius": 100000, "material_name": "wall"})";
  json.erase(json.find(wall), wall.size());
  const LoadedScene l = layer_scene(json);
  const RenderResult r = render_layers(l.scene, kAll, 4);
  EXPECT_EQ(r.image.extra.at("object_id")[0], 0.f);
  EXPECT_TRUE(std::isinf(r.image.extra.at("Z")[0]));
  EXPECT_EQ(r.image.extra.at("crypto_object00.G")[0], 0.f);
  EXPECT_EQ(r.image.extra.at("albedo.G")[0], 0.f);
}

// Every channel's bits of `b`'s window inside `a` (which covers the whole image).
void expect_window_equal(const RenderResult& a, const RenderResult& b, const std::string& what) {
  ASSERT_EQ(a.image.extra.size(), b.image.extra.size()) << what;
  for (const auto& [name, ch] : b.image.extra) {
    const std::vector<float>& full = a.image.extra.at(name);
    for (int y = 0; y < b.window.height(); ++y)
      for (int x = 0; x < b.window.width(); ++x) {
        const float u = full[size_t(y + b.window.y0) * size_t(a.image.width) + size_t(x + b.window.x0)];
        const float v = ch[size_t(y) * size_t(b.image.width) + size_t(x)];
        ASSERT_EQ(std::memcmp(&u, &v, 4), 0) << what << " " << name << " at " << x << "," << y;
      }
  }
}

TEST(LayerFilm, TilesWindowsAndThreadsGiveTheSameBits) {
  const LoadedScene l = load_scene_file(fs::path(TESSERA_SOURCE_DIR) / "scenes/cbox_glass.json");
  Scene scene = l.scene;
  scene.width = 64;
  scene.height = 48;
  const RenderResult whole = render_layers(scene, kAll, 4, 16);
  for (const int tile : {1, 7, 64}) expect_window_equal(whole, render_layers(scene, kAll, 4, tile), "tile");
  expect_window_equal(whole, render_layers(scene, kAll, 4, 5, PixelWindow{13, 9, 41, 30}), "crop");
  for (const int threads : {1, 3}) {
    tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(threads));
    tbb::task_arena arena(threads);
    RenderResult r;
    arena.execute([&] { r = render_layers(scene, kAll, 4, 8); });
    expect_window_equal(whole, r, "threads");
  }
}

TEST(LayerFilm, ColourIsBitwiseTheSameWithOrWithoutLayers) {
  const LoadedScene l = load_scene_file(fs::path(TESSERA_SOURCE_DIR) / "scenes/cbox_glass.json");
  Scene scene = l.scene;
  scene.width = 48;
  scene.height = 32;
  const RenderResult plain = render_layers(scene, LayerSet{}, 4);
  const RenderResult layered = render_layers(scene, kAll, 4);
  EXPECT_TRUE(plain.image.extra.empty());
  EXPECT_EQ(std::memcmp(plain.image.rgb.data(), layered.image.rgb.data(), plain.image.rgb.size() * 4), 0);
}

TEST(LayerFilm, AContinuedRenderEqualsAnUninterruptedOne) {
  const LoadedScene l = layer_scene(kWallAndSphere);
  RenderOptions o;
  o.spp = 8;
  o.seed = 5;
  o.layers = kAll;
  const RenderResult whole = render(l.scene, o);
  RenderOptions first = o;
  first.spp = 3;
  first.keep_state = true;
  RenderResult part = render(l.scene, first);
  StoredRender prev{std::move(part.image), std::move(part.state)};
  RenderOptions rest = o;
  rest.previous = &prev;
  expect_window_equal(whole, render(l.scene, rest), "continued");
}

TEST(Layers, NamesParseAndPrint) {
  EXPECT_TRUE(parse_layers("").empty());
  const LayerSet s = parse_layers("normal,albedo,crypto_object");
  EXPECT_EQ(layers_to_string(s), "albedo,normal,crypto_object");
  EXPECT_THROW(parse_layers("albedo,beauty"), std::invalid_argument);
  EXPECT_THROW(parse_layers("albedo,"), std::invalid_argument);
  EXPECT_EQ(layer_channels(Layer::kCryptoMaterial).size(), 12u);
  EXPECT_EQ(layer_channels(Layer::kCryptoMaterial)[5], "crypto_material01.G");
}

TEST(Cryptomatte, MurmurHashMatchesTheReferenceVectors) {
  EXPECT_EQ(murmur3_32(""), 0u);
  EXPECT_EQ(murmur3_32("hello"), 0x248bfa47u);
  EXPECT_EQ(murmur3_32("The quick brown fox jumps over the lazy dog"), 0x2e4ff723u);
  // Ids are never denormal, infinite or NaN.
  for (const char* name : {"", "a", "wall", "ball", "objects[0]"}) EXPECT_TRUE(std::isnormal(cryptomatte_float(cryptomatte_id(name))));
  const auto meta = cryptomatte_metadata("crypto_object", {"a", "a"});
  const std::string key = "cryptomatte/" + std::string(meta.begin()->first, 12, 7);
  EXPECT_EQ(meta.at(key + "/name"), "crypto_object");
  EXPECT_EQ(meta.at(key + "/hash"), "MurmurHash3_32");
  EXPECT_EQ(meta.at(key + "/conversion"), "uint32_to_float32");
}

}  // namespace
}  // namespace tessera
