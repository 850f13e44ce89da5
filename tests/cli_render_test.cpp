// Integration tests of `tessera render`: runs the built binary on small scenes and inspects what it writes (EXR
// windows, channels, pixel type and metadata, the PNG preview, the progress and summary lines) and how it fails.
#include "core/render.h"
#include "core/scene_loader.h"
#include "core/test_files.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/wait.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

namespace tessera {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

struct CliRun {
  int exit_code;    // the process's exit status (-1 when it did not exit normally)
  std::string err;  // what it wrote to stderr
};

class CliRender : public testing::TempDirTest {
 protected:
  // Runs `tessera render <args...>` (each argument shell-quoted) with stderr captured.
  CliRun tessera(const std::vector<std::string>& args) {
    // Built by appending: GCC 12 at -O3 warns (-Wrestrict, falsely) on "literal" + std::string chains.
    std::string cmd;
    auto quoted = [&](const std::string& a) {
      cmd += '\'';
      cmd += a;
      cmd += "' ";
    };
    quoted(TESSERA_BINARY);
    cmd += "render ";
    for (const std::string& a : args) quoted(a);
    const std::string log = file("stderr.txt").string();
    cmd += ">/dev/null 2>";
    quoted(log);
    const int status = std::system(cmd.c_str());
    std::ifstream in(log);
    std::string err((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, err};
  }
  std::string f(const std::string& name) const { return file(name).string(); }
  // A 20 x 12 scene: a textured floor under a point light and a rectangular emitter, a glass sphere, a sky.
  fs::path scene() {
    Image tex = Image::make(4, 4);
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) tex.set(x, y, Vec3(0.2f + 0.2f * float(x), 0.3f, 0.2f + 0.2f * float(y)));
    write_image("assets/tex.exr", tex);
    write("assets/floor.obj", testing::rect_obj(Vec3(-5.f, 0.f, -5.f), Vec3(0.f, 0.f, 10.f), Vec3(10.f, 0.f, 0.f), true));
    write("assets/light.obj", testing::rect_obj(Vec3(-0.5f, 2.f, -0.5f), Vec3(1.f, 0.f, 0.f), Vec3(0.f, 0.f, 1.f)));
    json s = testing::minimal_scene();
    s["film"]["resolution"] = {20, 12};
    s["integrator"]["spp"] = 2;
    s["integrator"]["point_light_position"] = {1, 3, 1};
    s["camera"] = {{"position", {0, 1, 4}}, {"look_at", {0, 0.5, 0}}, {"fov", 50}};
    s["textures"]["tex"] = {{"type", "image"}, {"path", "assets/tex.exr"}};
    s["textures"]["sky"] = {{"type", "constant"}, {"color", {0.2, 0.3, 0.5}}};
    s["materials"]["floor"] = {{"type", "diffuse"}, {"texture_name", "tex"}};
    s["materials"]["glass"] = {{"type", "refraction"}, {"eta", 1.5}};
    s["objects"] = json::array(
        {{{"type", "mesh"}, {"path", "assets/floor.obj"}, {"material_name", "floor"}},
         {{"type", "mesh"}, {"path", "assets/light.obj"}, {"light", {{"type", "area"}, {"radiance", {3, 3, 3}}}}},
         {{"type", "sphere"}, {"center", {0, 0.5, 0}}, {"radius", 0.5}, {"material_name", "glass"}},
         {{"type", "sphere"}, {"center", {1, 0.3, -0.5}}, {"radius", 0.3}, {"material_name", "white_diffuse"}}});
    s["environment_map"] = {{"texture_name", "sky"}};
    return write_scene("scene.json", s);
  }
};

TEST_F(CliRender, CropWindowsMetadataAndPixelsMatchTheLibrary) {
  const fs::path sc = scene();
  const CliRun r = tessera({sc.string(), "-o", f("out.exr"), "--crop", "3", "2", "14", "9", "--spp", "4", "--seed", "7", "--tile", "5"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ExrImage exr = read_exr(file("out.exr"));
  EXPECT_EQ(exr.data_window, (PixelWindow{3, 2, 14, 9}));
  EXPECT_EQ(exr.display_window, (PixelWindow{0, 0, 20, 12}));
  EXPECT_EQ(exr.metadata.at("tessera:spp"), "4");
  EXPECT_EQ(exr.metadata.at("tessera:seed"), "7");
  EXPECT_GE(std::stod(exr.metadata.at("tessera:renderSeconds")), 0.0);
  const LoadedScene loaded = load_scene_file(sc);
  EXPECT_EQ(exr.metadata.at("tessera:sceneHash"), loaded.scene.hash);
  // The binary's pixels are the library's, bit for bit (same seed, same window).
  RenderOptions ro;
  ro.seed = 7;
  ro.spp = 4;
  ro.window = exr.data_window;
  const RenderResult ref = render(loaded.scene, ro);
  ASSERT_EQ(exr.pixels.rgb.size(), ref.image.rgb.size());
  EXPECT_EQ(std::memcmp(exr.pixels.rgb.data(), ref.image.rgb.data(), ref.image.rgb.size() * sizeof(float)), 0);
  // A one-line summary with time, samples and ray rate.
  EXPECT_NE(r.err.find("11x7 px, 4 spp (308 samples)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Mrays/s"), std::string::npos) << r.err;
}

TEST_F(CliRender, HalfVarianceAndPreview) {
  const fs::path sc = scene();
  const CliRun r = tessera({sc.string(), "-o", f("half.exr"), "--half", "--variance", "--spp", "4", "--preview",
                           f("preview.png"), "--crop", "0", "0", "9", "5"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  {
    Imf::InputFile in(file("half.exr").c_str());
    const Imf::ChannelList& ch = in.header().channels();
    ASSERT_NE(ch.findChannel("R"), nullptr);
    EXPECT_EQ(ch.findChannel("R")->type, Imf::HALF);
    EXPECT_EQ(ch.findChannel("B")->type, Imf::HALF);
    for (const char* name : {"variance.R", "variance.G", "variance.B", "samples"}) {
      ASSERT_NE(ch.findChannel(name), nullptr) << name;
      EXPECT_EQ(ch.findChannel(name)->type, Imf::FLOAT) << name;
    }
  }
  const ExrImage exr = read_exr(file("half.exr"));
  for (float s : exr.pixels.extra.at("samples")) EXPECT_EQ(s, 4.f);
  double var_sum = 0;
  for (float v : exr.pixels.extra.at("variance.G")) {
    EXPECT_GE(v, 0.f);
    var_sum += v;
  }
  EXPECT_GT(var_sum, 0.0);  // the crop sees the noisy floor
  // Without --half, R is float.
  ASSERT_EQ(tessera({sc.string(), "-o", f("full.exr"), "-q"}).exit_code, 0);
  Imf::InputFile full(file("full.exr").c_str());
  EXPECT_EQ(full.header().channels().findChannel("R")->type, Imf::FLOAT);
  EXPECT_EQ(full.header().channels().findChannel("samples"), nullptr);
  // The preview is a PNG of the crop's size (IHDR width and height, big-endian, at bytes 16..23).
  std::ifstream png(file("preview.png"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(png)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 24u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  auto be32 = [&](size_t i) {
    return (uint32_t(uint8_t(bytes[i])) << 24) | (uint32_t(uint8_t(bytes[i + 1])) << 16) |
           (uint32_t(uint8_t(bytes[i + 2])) << 8) | uint32_t(uint8_t(bytes[i + 3]));
  };
  EXPECT_EQ(be32(16), 9u);
  EXPECT_EQ(be32(20), 5u);
}

TEST_F(CliRender, ProgressReportsTilesRaysAndEta) {
  const CliRun r = tessera({scene().string(), "-o", f("p.exr"), "--tile", "4"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // On a pipe the bar prints a line per 10%: the last one has every tile.
  EXPECT_NE(r.err.find("100%  15/15 tiles"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ETA"), std::string::npos) << r.err;
}

// The job API carries every sampling option (protocol::SamplingSettings): through the farm they change the pixels
// exactly as they do in one process.
TEST_F(CliRender, WorkersCarryEverySamplingOption) {
  const std::vector<std::string> opts = {"-q", "--replicates", "2", "--env-sampling", "uniform", "--bvh", "median",
                                         "--area-sampling", "area", "--target-error", "0.3", "--min-spp", "4",
                                         "--max-spp", "16", "--error-floor", "0.5"};
  std::vector<std::string> local = {scene().string(), "-o", f("l.exr")};
  local.insert(local.end(), opts.begin(), opts.end());
  std::vector<std::string> farm = {scene().string(), "-o", f("w.exr"), "--workers", "1", "--farm-tile", "4"};
  farm.insert(farm.end(), opts.begin(), opts.end());
  const CliRun l = tessera(local);
  ASSERT_EQ(l.exit_code, 0) << l.err;
  const CliRun w = tessera(farm);
  ASSERT_EQ(w.exit_code, 0) << w.err;
  EXPECT_EQ(read_exr(file("l.exr")).pixels.rgb, read_exr(file("w.exr")).pixels.rgb);
}

// --strict is about reading the file here, which the coordinator does not repeat: refused, never silently dropped.
TEST_F(CliRender, WorkersRefuseStrict) {
  const CliRun r = tessera({scene().string(), "-o", f("w.exr"), "-q", "--workers", "1", "--strict"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--strict"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(file("w.exr")));
}

TEST_F(CliRender, BadInputFailsWithTheJsonPath) {
  json s = testing::minimal_scene();
  s["objects"][0]["radius"] = -1;
  write_scene("bad.json", s);
  CliRun r = tessera({f("bad.json"), "-o", f("bad.exr"), "-q"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("objects[0].radius"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(file("bad.exr")));

  s = testing::minimal_scene();
  s["integrator"]["type"] = "bdpt";
  write_scene("bdpt.json", s);
  r = tessera({f("bdpt.json"), "-o", f("bdpt.exr"), "-q"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("integrator.type"), std::string::npos) << r.err;
  r = tessera({f("bdpt.json"), "-o", f("bdpt.exr"), "-q", "--integrator", "direct"});
  EXPECT_EQ(r.exit_code, 0) << r.err;

  s = testing::minimal_scene();
  s["objects"][0]["colour"] = "red";
  write_scene("unknown.json", s);
  r = tessera({f("unknown.json"), "-o", f("u.exr"), "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("objects[0].colour"), std::string::npos) << r.err;  // a warning
  r = tessera({f("unknown.json"), "-o", f("u.exr"), "-q", "--strict"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("objects[0].colour"), std::string::npos) << r.err;

  r = tessera({scene().string(), "-o", f("c.exr"), "-q", "--crop", "0", "0", "21", "5"});  // outside the 20 x 12 film
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--crop"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace tessera
