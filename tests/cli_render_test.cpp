// Integration tests of `tessera render`: runs the built binary on small scenes and inspects what it writes (EXR
// windows, channels, pixel type and metadata, the PNG preview, the progress and summary lines) and how it fails.
#include "cli/interrupt_guard.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"
#include "tests/support/cli_run.h"
#include "tests/spp_scale.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <sys/wait.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace tessera {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

using testing::CliRun;

class CliRender : public testing::TempDirTest {
 protected:
  // Runs `tessera <command> <args...>` (each argument shell-quoted) with stderr captured.
  CliRun tessera(const std::vector<std::string>& args, const std::string& command = "render") {
    // Built by appending: GCC 12 at -O3 warns (-Wrestrict, falsely) on "literal" + std::string chains.
    std::string cmd;
    auto quoted = [&](const std::string& a) {
      cmd += '\'';
      cmd += a;
      cmd += "' ";
    };
    quoted(TESSERA_BINARY);
    cmd += command;
    cmd += ' ';
    for (const std::string& a : args) quoted(a);
    const std::string log = file("stderr.txt").string();
    cmd += "2>";
    quoted(log);
    cmd += "1>&2";  // `submit` logs to stdout; `render` writes nothing there
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
    s["integrator"]["spp"] = testing::scaled_spp(2);
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
  const uint32_t spp = testing::scaled_spp(4);
  const CliRun r = tessera({sc.string(), "-o", f("out.exr"), "--crop", "3", "2", "14", "9", "--spp", std::to_string(spp),
                            "--seed", "7", "--tile", "5"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ExrImage exr = read_exr(file("out.exr"));
  EXPECT_EQ(exr.data_window, (PixelWindow{3, 2, 14, 9}));
  EXPECT_EQ(exr.display_window, (PixelWindow{0, 0, 20, 12}));
  EXPECT_EQ(exr.metadata.at("tessera:spp"), std::to_string(spp));
  EXPECT_EQ(exr.metadata.at("tessera:seed"), "7");
  EXPECT_GE(std::stod(exr.metadata.at("tessera:renderSeconds")), 0.0);
  const LoadedScene loaded = load_scene_file(sc);
  EXPECT_EQ(exr.metadata.at("tessera:sceneHash"), loaded.scene.hash);
  // The binary's pixels are the library's, bit for bit (same seed, same window).
  RenderOptions ro;
  ro.seed = 7;
  ro.spp = spp;
  ro.window = exr.data_window;
  const RenderResult ref = render(loaded.scene, ro);
  ASSERT_EQ(exr.pixels.rgb.size(), ref.image.rgb.size());
  EXPECT_EQ(std::memcmp(exr.pixels.rgb.data(), ref.image.rgb.data(), ref.image.rgb.size() * sizeof(float)), 0);
  // A one-line summary with time, samples and ray rate.
  const std::string summary = "11x7 px, " + std::to_string(spp) + " spp (" + std::to_string(77 * spp) + " samples)";
  EXPECT_NE(r.err.find(summary), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Mrays/s"), std::string::npos) << r.err;
}

TEST_F(CliRender, HalfVarianceAndPreview) {
  const fs::path sc = scene();
  const uint32_t spp = std::max(2u, testing::scaled_spp(4));  // a variance needs two samples
  const CliRun r = tessera({sc.string(), "-o", f("half.exr"), "--half", "--variance", "--spp", std::to_string(spp),
                            "--preview", f("preview.png"), "--crop", "0", "0", "9", "5"});
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
  for (float s : exr.pixels.extra.at("samples")) EXPECT_EQ(s, float(spp));
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
  // On a pipe the bar prints a line per 10% with an ETA; the last one, once, has every tile and the time taken.
  const size_t last = r.err.find("100%  15/15 tiles");
  ASSERT_NE(last, std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("100%", last + 1), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" Mrays/s  in ", last), std::string::npos) << r.err;
  EXPECT_LT(r.err.find("ETA "), last) << r.err;
}

// --timing accounts for the wall time: its parts add up, and the idle thread time lies within the threads' time.
TEST_F(CliRender, TimingAccountsForTheWallTime) {
  const CliRun r = tessera({scene().string(), "-o", f("t.exr"), "-q", "--threads", "2", "--timing"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  double load = 0, film = 0, threaded = 0, idle = 0, idle_pct = 0, write = 0, total = 0, outside = 0, outside_pct = 0;
  int threads = 0;
  const size_t at = r.err.find("timing: ");
  ASSERT_NE(at, std::string::npos) << r.err;
  ASSERT_EQ(std::sscanf(r.err.c_str() + at,
                        "timing: load %lfs + film %lfs + threaded render %lfs on %d thread(s), idle %lf thread-s (%lf%%) "
                        "+ write %lfs = %lfs; outside the threaded render %lfs (%lf%%)",
                        &load, &film, &threaded, &threads, &idle, &idle_pct, &write, &total, &outside, &outside_pct),
            10)
      << r.err;
  EXPECT_GE(threads, 1);
  EXPECT_LE(threads, 2);
  EXPECT_GE(idle, 0.0);
  // Each figure is printed to 0.1 ms; the parts are spans between the same instants, so only rounding separates
  // their sum from the total, however loaded the machine is.
  EXPECT_LE(idle, threads * (threaded + 0.0005) + 0.0005);
  EXPECT_NEAR(load + film + threaded + write, total, 0.00025);
  EXPECT_NEAR(outside, total - threaded, 0.00015);
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

// One rule for exit statuses (cli/exit_status.h, README "Exit status"): whatever is refused before any work exits 2
// and writes nothing, whether CLI11 or a command refused it; --help and --version exit 0.
TEST_F(CliRender, EveryRefusalBeforeAnyWorkExitsTwo) {
  const fs::path sc = scene();
  write("broken.json", "{\"camera\": ");
  write("not.exr", "not an EXR");
  const std::vector<std::pair<std::vector<std::string>, std::string>> refused = {
      {{sc.string(), "-o", f("o.exr"), "--no-such-flag"}, "render"},         // CLI11: unknown option
      {{sc.string(), "-o", f("o.exr"), "--spp", "0"}, "render"},             // CLI11: out of range
      {{sc.string()}, "render"},                                             // CLI11: -o missing
      {{f("missing.json"), "-o", f("o.exr")}, "render"},                     // CLI11: no such file
      {{f("broken.json"), "-o", f("o.exr")}, "render"},                      // the scene loader
      {{sc.string(), "-o", f("o.exr"), "--resume", f("not.exr")}, "render"},  // the resume file
      {{f("not.exr"), "-o", f("o.exr")}, "merge"},                           // a tile that is no EXR
      {{"no-such-subcommand"}, ""},
  };
  for (const auto& [args, command] : refused) {
    const CliRun r = tessera(args, command);
    EXPECT_EQ(r.exit_code, 2) << command << " " << ::testing::PrintToString(args) << ": " << r.err;
    EXPECT_FALSE(fs::exists(file("o.exr"))) << ::testing::PrintToString(args);
  }
  EXPECT_EQ(tessera({"--help"}).exit_code, 0);
  EXPECT_EQ(tessera({"--version"}, "").exit_code, 0);
}

// --version names the release and the commit the binary was built from ("unknown" outside a git checkout).
TEST_F(CliRender, VersionNamesTheReleaseAndTheCommit) {
  const CliRun r = tessera({"--version"}, "");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.err.find(std::string("tessera ") + TESSERA_VERSION + " (commit "), std::string::npos) << r.err;
}

TEST_F(CliRender, BadInputFailsWithTheJsonPath) {
  json s = testing::minimal_scene();
  s["objects"][0]["radius"] = -1;
  write_scene("bad.json", s);
  CliRun r = tessera({f("bad.json"), "-o", f("bad.exr"), "-q"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("objects[0].radius"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(file("bad.exr")));

  s = testing::minimal_scene();
  s["integrator"]["type"] = "photon";
  write_scene("photon.json", s);
  r = tessera({f("photon.json"), "-o", f("photon.exr"), "-q"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("integrator.type"), std::string::npos) << r.err;
  r = tessera({f("photon.json"), "-o", f("photon.exr"), "-q", "--integrator", "direct"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // bdpt renders with the path tracer and says so on stderr.
  s["integrator"]["type"] = "bdpt";
  write_scene("bdpt.json", s);
  r = tessera({f("bdpt.json"), "-o", f("bdpt.exr"), "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("rendered with the unidirectional path tracer"), std::string::npos) << r.err;

  s = testing::minimal_scene();
  s["objects"][0]["colour"] = "red";
  write_scene("unknown.json", s);
  r = tessera({f("unknown.json"), "-o", f("u.exr"), "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("objects[0].colour"), std::string::npos) << r.err;  // a warning
  r = tessera({f("unknown.json"), "-o", f("u.exr"), "-q", "--strict"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("objects[0].colour"), std::string::npos) << r.err;

  r = tessera({scene().string(), "-o", f("c.exr"), "-q", "--crop", "0", "0", "21", "5"});  // outside the 20 x 12 film
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--crop"), std::string::npos) << r.err;
}

// The bytes of a file.
std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Bitwise equality of two EXRs' windows, colours and float channels.
void expect_same_exr(const fs::path& a, const fs::path& b) {
  const ExrImage x = read_exr(a), y = read_exr(b);
  EXPECT_EQ(x.data_window, y.data_window);
  ASSERT_EQ(x.pixels.rgb.size(), y.pixels.rgb.size());
  EXPECT_EQ(std::memcmp(x.pixels.rgb.data(), y.pixels.rgb.data(), x.pixels.rgb.size() * sizeof(float)), 0) << a << " vs " << b;
  for (const auto& [name, ch] : x.pixels.extra) {
    ASSERT_TRUE(y.pixels.extra.count(name)) << name;
    EXPECT_EQ(std::memcmp(ch.data(), y.pixels.extra.at(name).data(), ch.size() * sizeof(float)), 0) << name;
  }
}

// The bytes write_exr writes for what `path` holds (pixels and channels as read back, windows, ZIP, half colours
// when its R channel is half, its metadata).
std::vector<uint8_t> one_shot_bytes(const fs::path& path) {
  const ExrImage e = read_exr(path);
  Imf::InputFile in(path.c_str());
  EXPECT_EQ(in.header().compression(), Imf::ZIP_COMPRESSION) << path;
  ExrWriteOptions o;
  o.half = in.header().channels().findChannel("R")->type == Imf::HALF;
  o.data_window = e.data_window;
  o.display_window = e.display_window;
  o.metadata = e.metadata;
  return encode_exr(e.pixels, o);
}

std::vector<uint8_t> file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// `render` compresses the EXR band by band while it renders: the file is byte for byte the one-shot write of its
// contents, with every channel and attribute, on one thread or several, for crops and tiles of odd sizes, half
// colours, variance and state channels, partial files and resumed ones.
TEST_F(CliRender, FileIsTheOneShotWriteOfItsContents) {
  const std::string sc = scene().string();
  const std::vector<std::vector<std::string>> runs = {
      {sc, "-o", f("a.exr"), "-q"},
      {sc, "-o", f("b.exr"), "-q", "--threads", "1", "--tile", "3"},
      {sc, "-o", f("c.exr"), "-q", "--threads", "2", "--tile", "5", "--crop", "1", "1", "20", "12", "--half", "--variance"},
      {sc, "-o", f("d.exr"), "-q", "--threads", "3", "--tile", "2", "--resumable", "--replicates", "2", "--half"},
      {sc, "-o", f("e.exr"), "-q", "--tile", "4", "--tile-budget", "5", "--variance"},  // partial: exit code 3
      {sc, "-o", f("f.exr"), "-q", "--resume", f("e.exr"), "--tile", "7", "--half"},
      {sc, "-o", f("g.exr"), "-q", "--resume", f("d.exr"), "--spp", std::to_string(2 * testing::scaled_spp(2))},
  };
  for (const std::vector<std::string>& args : runs) {
    const CliRun r = tessera(args);
    ASSERT_EQ(r.exit_code, args[2] == f("e.exr") ? 3 : 0) << r.err;
    EXPECT_EQ(file_bytes(args[2]), one_shot_bytes(args[2])) << args[2];
  }
  for (const auto& entry : fs::directory_iterator(file("")))
    EXPECT_NE(entry.path().extension(), ".tmp") << entry.path();  // no temp file left
  EXPECT_TRUE(read_exr(file("e.exr")).metadata.count("tessera:partial"));
  EXPECT_TRUE(read_exr(file("g.exr")).pixels.uint_extra.count("tessera.state.sum.R.hi"));
}

// An output that cannot be written is an error before any rendering, and nothing existing is touched.
TEST_F(CliRender, UnwritableOutputFailsBeforeRendering) {
  const fs::path sc = scene();
  CliRun r = tessera({sc.string(), "-o", "/no/such/dir/out.exr", "--spp", "1"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("cannot write the output \"/no/such/dir/out.exr\": the folder \"/no/such/dir\" does not exist"),
            std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("tiles"), std::string::npos) << r.err;  // no progress: nothing was rendered
  fs::create_directories(file("folder.exr"));
  r = tessera({sc.string(), "-o", f("folder.exr"), "--spp", "1"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("it is a folder"), std::string::npos) << r.err;
  // A good earlier result is neither clobbered nor joined by half files when only the preview is unwritable.
  ASSERT_EQ(tessera({sc.string(), "-o", f("good.exr"), "-q", "--spp", "1"}).exit_code, 0);
  const std::string before = slurp(file("good.exr"));
  const auto entries = [&] {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(file(""))) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  };
  const auto listing = entries();
  r = tessera({sc.string(), "-o", f("good.exr"), "-q", "--spp", "2", "--preview", f("missing/p.png")});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("cannot write the preview"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(file("good.exr")), before);
  EXPECT_EQ(entries(), listing);
  // `submit -o` checks before contacting the coordinator (nothing listens on port 1).
  r = tessera({sc.string(), "--coordinator", "http://127.0.0.1:1", "-o", "/no/such/dir/out.exr", "-q"}, "submit");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("the folder \"/no/such/dir\" does not exist"), std::string::npos) << r.err;
}

// --tile-budget stops after N tiles and writes a partial EXR (unrendered pixels have 0 in tessera.samples);
// --resume finishes it bit for bit as one uninterrupted render, with the settings taken from the file.
TEST_F(CliRender, PartialRenderResumesBitwise) {
  const fs::path sc = scene();
  ASSERT_EQ(tessera({sc.string(), "-o", f("whole.exr"), "-q", "--spp", "3", "--seed", "5", "--variance", "--crop", "1",
                     "2", "17", "10"}).exit_code,
            0);
  CliRun r = tessera({sc.string(), "-o", f("part.exr"), "--spp", "3", "--seed", "5", "--variance", "--crop", "1", "2",
                      "17", "10", "--tile", "4", "--tile-budget", "4", "--half"});
  ASSERT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("--resume"), std::string::npos) << r.err;
  const ExrImage part = read_exr(file("part.exr"));
  EXPECT_EQ(part.metadata.at("tessera:partial"), "64 of 128 pixels");  // 4 of the 8 tiles of 4x4
  const auto& samples = part.pixels.uint_extra.at("tessera.samples");
  EXPECT_EQ(std::count(samples.begin(), samples.end(), 3u), 64);
  EXPECT_EQ(std::count(samples.begin(), samples.end(), 0u), 128 - 64);
  EXPECT_EQ(part.pixels.uint_extra.count("tessera.state.sum.R.hi"), 0u);  // no exact sums without --resumable
  // Finished in two more slices, the second one writing over its own input.
  r = tessera({sc.string(), "-o", f("part2.exr"), "-q", "--resume", f("part.exr"), "--tile", "3", "--tile-budget", "5"});
  ASSERT_EQ(r.exit_code, 3) << r.err;
  r = tessera({sc.string(), "-o", f("part2.exr"), "-q", "--resume", f("part2.exr")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_exr(file("part2.exr"), file("whole.exr"));
  EXPECT_FALSE(read_exr(file("part2.exr")).metadata.count("tessera:partial"));
  // A partial file cannot be refined (no exact sums), nor resumed against another scene or with other settings.
  r = tessera({sc.string(), "-o", f("x.exr"), "-q", "--resume", f("part.exr"), "--spp", "6"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--resumable"), std::string::npos) << r.err;
  r = tessera({sc.string(), "-o", f("x.exr"), "-q", "--resume", f("part.exr"), "--seed", "6"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--seed excludes --resume"), std::string::npos) << r.err;
  json other = testing::minimal_scene();
  other["film"]["resolution"] = {20, 12};
  write_scene("other.json", other);
  r = tessera({f("other.json"), "-o", f("x.exr"), "-q", "--resume", f("part.exr")});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("another scene"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(file("x.exr")));
}

// --resumable keeps each pixel's exact sums, so --resume --spp 4N refines an N-spp render to exactly the 4N one.
TEST_F(CliRender, ResumableRenderRefinesBitwise) {
  const fs::path sc = scene();
  ASSERT_EQ(tessera({sc.string(), "-o", f("n.exr"), "-q", "--spp", "2", "--replicates", "2", "--variance", "--resumable"}).exit_code, 0);
  ASSERT_EQ(tessera({sc.string(), "-o", f("ref.exr"), "-q", "--spp", "8", "--replicates", "2", "--variance"}).exit_code, 0);
  CliRun r = tessera({sc.string(), "-o", f("4n.exr"), "-q", "--resume", f("n.exr"), "--spp", "8"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_exr(file("4n.exr"), file("ref.exr"));
  EXPECT_EQ(read_exr(file("4n.exr")).metadata.at("tessera:spp"), "8");
  r = tessera({sc.string(), "-o", f("x.exr"), "-q", "--resume", f("4n.exr"), "--spp", "4"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("cannot take samples away"), std::string::npos) << r.err;
  // A finished render without --resumable cannot be continued; an adaptive one cannot be refined.
  r = tessera({sc.string(), "-o", f("x.exr"), "-q", "--resume", f("ref.exr"), "--spp", "16"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("tessera.samples"), std::string::npos) << r.err;
  ASSERT_EQ(tessera({sc.string(), "-o", f("a.exr"), "-q", "--target-error", "0.3", "--resumable"}).exit_code, 0);
  r = tessera({sc.string(), "-o", f("x.exr"), "-q", "--resume", f("a.exr"), "--spp", "64"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("adaptive"), std::string::npos) << r.err;
}

// SIGINT and SIGTERM set the flag `render` passes to the renderer as its cancel flag (the same path --tile-budget
// takes, tested above), only while a guard is installed; a new guard starts cleared.
TEST(InterruptGuard, SignalsSetTheFlagOnlyWhileInstalled) {
  using cli::InterruptGuard;
  struct sigaction before {};
  sigaction(SIGINT, nullptr, &before);
  for (const int sig : {SIGINT, SIGTERM}) {
    InterruptGuard guard;
    EXPECT_FALSE(InterruptGuard::interrupted());
    std::raise(sig);  // the handler runs before raise returns
    EXPECT_TRUE(InterruptGuard::interrupted()) << sig;
  }
  struct sigaction after {};
  sigaction(SIGINT, nullptr, &after);
  EXPECT_EQ(after.sa_handler, before.sa_handler);
}

// A guard made inside another (a sequence's frame inside the sequence) keeps a signal that arrived before it, so a
// Ctrl-C between two frames still stops the sequence; the outermost guard starts cleared.
TEST(InterruptGuard, NestedGuardKeepsTheOuterSignal) {
  using cli::InterruptGuard;
  {
    InterruptGuard sequence;
    std::raise(SIGINT);
    {
      InterruptGuard frame;
      EXPECT_TRUE(InterruptGuard::interrupted());
    }
    EXPECT_TRUE(InterruptGuard::interrupted());
  }
  InterruptGuard next;
  EXPECT_FALSE(InterruptGuard::interrupted());
}

}  // namespace
}  // namespace tessera
