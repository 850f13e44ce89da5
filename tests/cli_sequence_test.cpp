// `tessera render` of sequences, run as a process: every frame is bitwise the render of its scene alone, finished
// frames are skipped and the others rendered again (--skip-existing) or continued (--resume), Ctrl-C stops the
// sequence after writing the frame in progress, and each bad input is refused with status 2 before anything is written.
#include "core/image/image.h"
#include "tests/exr_diff.h"
#include "tests/support/test_files.h"
#include "tests/support/cli_run.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

namespace tessera {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

using testing::CliRun;

// Which file a path names and when it was last written: a file written again (always through a rename) differs.
struct FileIdentity {
  ino_t inode = 0;
  int64_t mtime_ns = 0;
  bool operator==(const FileIdentity&) const = default;
};

FileIdentity identity(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return {};
  return {st.st_ino, int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec};
}

class CliSequence : public testing::TempDirTest {
 protected:
  // The arguments of `tessera render ARGS...`, for a log.
  static std::string joined(const std::vector<std::string>& args) {
    std::string s;
    for (const std::string& a : args) s += a + " ";
    return s;
  }
  // Runs `tessera render <args...>` in the test's folder (so that relative paths are short), stderr captured.
  CliRun render(const std::vector<std::string>& args) {
    const fs::path log = file("stderr.txt");
    const pid_t pid = ::fork();
    if (pid == 0) {
      start(args, log);
      ::_exit(127);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read_text(log)};
  }
  // In a child process: becomes `tessera render <args...>` in the test's folder with stderr going to `log`.
  void start(const std::vector<std::string>& args, const fs::path& log) const {
    if (::chdir(dir_.c_str()) != 0) return;
    std::ofstream(log, std::ios::trunc).close();
    if (!std::freopen(log.c_str(), "w", stderr)) return;
    std::vector<std::string> all = {TESSERA_BINARY, "render"};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
  }
  static std::string read_text(const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  // Frame k's scene: a sphere on a floor under an area light and a sky, path traced, seen from a camera that moves
  // with k; `size` pixels square at `spp`.
  json frame_scene(int k, int size = 24, int spp = 4) const {
    json s;
    s["integrator"] = {{"type", "path"}, {"spp", spp}, {"max_depth", 4}};
    s["film"] = {{"resolution", {size, size}}};
    s["camera"] = {{"position", {0.25 * k, 1.5, 4}}, {"look_at", {0, 0.5, 0}}, {"ref_up", {0, 1, 0}}, {"fov", 45}};
    s["textures"] = {{"white", {{"type", "constant"}, {"color", {0.8, 0.8, 0.8}}}},
                     {"sky", {{"type", "constant"}, {"color", {0.3, 0.4, 0.5}}}}};
    s["materials"] = {{"white", {{"type", "diffuse"}, {"texture_name", "white"}}}};
    s["objects"] = json::array(
        {{{"type", "sphere"}, {"center", {0, -1000, 0}}, {"radius", 1000}, {"material_name", "white"}},
         {{"type", "sphere"}, {"center", {0, 0.6, 0}}, {"radius", 0.6}, {"material_name", "white"}},
         {{"type", "sphere"}, {"center", {0.5, 2.5, 0.5}}, {"radius", 0.4},
          {"light", {{"type", "area"}, {"radiance", {5, 5, 5}}}}}});
    s["environment_map"] = {{"texture_name", "sky"}};
    return s;
  }
  // Writes shot/frame_0001.json ... shot/frame_000N.json.
  void write_frames(int n) const {
    for (int k = 1; k <= n; ++k) write_scene(frame("shot/frame_", k, ".json"), frame_scene(k));
  }
  // "shot/frame_0003.json" for frame("shot/frame_", 3, ".json").
  static std::string frame(const std::string& prefix, int k, const std::string& suffix) {
    char digits[16];
    std::snprintf(digits, sizeof digits, "%04d", k);
    return prefix + digits + suffix;
  }
  // Expects the EXRs a and b (paths in the test's folder) to be bitwise identical, metadata included.
  void expect_same_exr(const std::string& a, const std::string& b) const {
    const std::vector<std::string> diffs = testing::exr_differences(file(a), file(b));
    EXPECT_TRUE(diffs.empty()) << a << " vs " << b << ": " << diffs.front();
  }
  // Renders frame k's scene alone, as a reference.
  void render_alone(int k, const std::string& output, const std::vector<std::string>& options = {}) {
    std::vector<std::string> args = {frame("shot/frame_", k, ".json"), "-o", output, "-q"};
    args.insert(args.end(), options.begin(), options.end());
    const CliRun r = render(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  // The files in folder `name` of the test's folder.
  std::vector<std::string> files_in(const std::string& name) const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(file(name))) out.push_back(e.path().filename().string());
    return out;
  }
};

// Both forms of a sequence give each frame exactly the file `render FRAME.json -o FRAME.exr` writes, with a line per
// frame; a step picks every other frame; --preview takes a '#' pattern too.
TEST_F(CliSequence, FramesAreBitwiseTheirSingleRenders) {
  write_frames(3);
  fs::create_directories(file("out"));
  fs::create_directories(file("pat"));
  fs::create_directories(file("ref"));
  for (int k = 1; k <= 3; ++k) render_alone(k, frame("ref/f_", k, ".exr"));
  // The list of files a shell glob gives, in the shell's (name) order.
  CliRun r = render({"shot/frame_0001.json", "shot/frame_0002.json", "shot/frame_0003.json", "-o", "out/f_####.exr",
                     "-q", "--preview", "out/p_##.png"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (int k = 1; k <= 3; ++k) {
    expect_same_exr(frame("out/f_", k, ".exr"), frame("ref/f_", k, ".exr"));
    EXPECT_TRUE(fs::exists(file("out/p_0" + std::to_string(k) + ".png"))) << k;
    const std::string line = "frame " + std::to_string(k) + " (" + std::to_string(k) + " of 3): " +
                             frame("shot/frame_", k, ".json") + " -> " + frame("out/f_", k, ".exr");
    EXPECT_NE(r.err.find(line), std::string::npos) << r.err;
  }
  EXPECT_NE(r.err.find("3 frame(s): 3 rendered, 0 skipped as complete"), std::string::npos) << r.err;
  // The pattern form with a step.
  r = render({"shot/frame_####.json", "--frames", "1-3x2", "-o", "pat/f_####.exr", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(files_in("pat").size(), 2u);
  expect_same_exr("pat/f_0001.exr", "ref/f_0001.exr");
  expect_same_exr("pat/f_0003.exr", "ref/f_0003.exr");
  EXPECT_NE(r.err.find("frame 3 (2 of 2)"), std::string::npos) << r.err;
  // With the sampling options of the command.
  render_alone(2, "ref/seeded.exr", {"--seed", "11", "--spp", "3", "--variance", "--half"});
  r = render({"shot/frame_####.json", "--frames", "2", "-o", "pat/s_#.exr", "-q", "--seed", "11", "--spp", "3",
              "--variance", "--half"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_exr("pat/s_2.exr", "ref/seeded.exr");
}

// --skip-existing keeps a complete frame as it is (not even rewritten) and renders again, saying why, a partial one
// (--tile-budget), one rendered with another seed, one of another scene and a file that is not an EXR.
TEST_F(CliSequence, SkipExistingRendersAgainOnlyWhatIsNotComplete) {
  write_frames(5);
  fs::create_directories(file("out"));
  fs::create_directories(file("ref"));
  for (int k = 1; k <= 5; ++k) render_alone(k, frame("ref/f_", k, ".exr"));
  CliRun r = render({"shot/frame_####.json", "--frames", "1-5", "-o", "out/f_####.exr", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const FileIdentity complete = identity(file("out/f_0001.exr"));
  // Frame 2 partial, frame 3 at another seed, frame 4 from another scene, frame 5 not an EXR.
  r = render({"shot/frame_0002.json", "-o", "out/f_0002.exr", "-q", "--tile", "8", "--tile-budget", "2"});
  ASSERT_EQ(r.exit_code, 3) << r.err;
  render_alone(3, "out/f_0003.exr", {"--seed", "5"});
  write_scene("other.json", frame_scene(9));
  ASSERT_EQ(render({"other.json", "-o", "out/f_0004.exr", "-q"}).exit_code, 0);
  write("out/f_0005.exr", "not an image");

  r = render({"shot/frame_####.json", "--frames", "1-5", "-o", "out/f_####.exr", "-q", "--skip-existing"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(identity(file("out/f_0001.exr")), complete);
  for (int k = 1; k <= 5; ++k) expect_same_exr(frame("out/f_", k, ".exr"), frame("ref/f_", k, ".exr"));
  for (const char* line : {"frame 1: out/f_0001.exr is complete, skipped",
                           "frame 2: out/f_0002.exr is partial (128 of 576 pixels), rendering it again",
                           "frame 3: out/f_0003.exr was rendered with tessera:seed 5, not 0, rendering it again",
                           "frame 4: out/f_0004.exr was rendered from another scene (or other assets), rendering it "
                           "again",
                           "frame 5: out/f_0005.exr does not read (not an OpenEXR file", "4 rendered, 1 skipped"})
    EXPECT_NE(r.err.find(line), std::string::npos) << line << "\n" << r.err;
  EXPECT_EQ(r.err.find("frame 1 (1 of 5)"), std::string::npos) << r.err;

  // Everything complete: nothing is written; with other settings, everything is rendered again.
  std::vector<FileIdentity> before;
  for (int k = 1; k <= 5; ++k) before.push_back(identity(file(frame("out/f_", k, ".exr"))));
  r = render({"shot/frame_####.json", "--frames", "1-5", "-o", "out/f_####.exr", "-q", "--skip-existing"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("0 rendered, 5 skipped"), std::string::npos) << r.err;
  for (int k = 1; k <= 5; ++k) EXPECT_EQ(identity(file(frame("out/f_", k, ".exr"))), before[size_t(k - 1)]) << k;
  r = render(
      {"shot/frame_####.json", "--frames", "1-5", "-o", "out/f_####.exr", "-q", "--skip-existing", "--spp", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("frame 1: out/f_0001.exr was rendered with tessera:spp 4, not 2"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("5 rendered, 0 skipped"), std::string::npos) << r.err;
  // One scene file with --skip-existing is a sequence of one frame.
  r = render({"shot/frame_0001.json", "-o", "out/f_0001.exr", "-q", "--skip-existing", "--spp", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("0 rendered, 1 skipped"), std::string::npos) << r.err;
}

// --resume with the -o pattern: complete frames are skipped, partial ones continued from their file, missing ones
// rendered, all with the settings the files record (as --resume takes them from one file); files that disagree
// on them are refused before anything is rendered.
TEST_F(CliSequence, ResumeContinuesTheSequenceWithItsFilesSettings) {
  write_frames(3);
  fs::create_directories(file("out"));
  fs::create_directories(file("ref"));
  const std::vector<std::string> settings = {"--seed", "7", "--spp", "3"};
  for (int k = 1; k <= 3; ++k) render_alone(k, frame("ref/f_", k, ".exr"), settings);
  render_alone(1, "out/f_0001.exr", settings);
  std::vector<std::string> partial = {"shot/frame_0002.json", "-o", "out/f_0002.exr", "-q", "--tile", "8",
                                      "--tile-budget", "3"};
  partial.insert(partial.end(), settings.begin(), settings.end());
  CliRun r = render(partial);
  ASSERT_EQ(r.exit_code, 3) << r.err;
  const FileIdentity complete = identity(file("out/f_0001.exr"));

  // The spp is taken from the files too: 3, not the scenes' 4.
  r = render({"shot/frame_####.json", "--frames", "1-3", "-o", "out/f_####.exr", "-q", "--resume", "out/f_####.exr"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(identity(file("out/f_0001.exr")), complete);
  for (int k = 1; k <= 3; ++k) expect_same_exr(frame("out/f_", k, ".exr"), frame("ref/f_", k, ".exr"));
  for (const char* line : {"frame 1: out/f_0001.exr is complete, skipped",
                           "frame 2: continuing out/f_0002.exr, which is partial (192 of 576 pixels)",
                           "frame 3 (3 of 3)", "2 rendered, 1 skipped"})
    EXPECT_NE(r.err.find(line), std::string::npos) << line << "\n" << r.err;

  // Frame 3 rendered with another seed: the files disagree, and nothing is rendered or written.
  render_alone(3, "out/f_0003.exr", {"--seed", "8", "--spp", "3"});
  ASSERT_EQ(render(partial).exit_code, 3);
  const FileIdentity partial_file = identity(file("out/f_0002.exr"));
  r = render({"shot/frame_####.json", "--frames", "1-3", "-o", "out/f_####.exr", "-q", "--resume", "out/f_####.exr"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("frame 3: out/f_0003.exr was rendered with tessera:seed 8, not 7 as frame 1's out/f_0001.exr "
                       "was"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(identity(file("out/f_0002.exr")), partial_file);
}

// A file's layout counts too (half colours, variance channels, exact sums); and --resume --spp raises frames rendered
// with --resumable to more samples, bitwise as if rendered at those from the start.
TEST_F(CliSequence, LayoutCountsAndResumableFramesAreRaised) {
  write_frames(2);
  fs::create_directories(file("out"));
  fs::create_directories(file("ref"));
  const std::vector<std::string> seq = {"shot/frame_0001.json", "shot/frame_0002.json", "-o", "out/f_####.exr", "-q"};
  const auto with = [&](const std::vector<std::string>& more) {
    std::vector<std::string> a = seq;
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  ASSERT_EQ(render(with({"--half"})).exit_code, 0);
  CliRun r = render(with({"--skip-existing", "--half"}));
  EXPECT_NE(r.err.find("0 rendered, 2 skipped"), std::string::npos) << r.err;
  r = render(with({"--skip-existing"}));
  EXPECT_NE(r.err.find("frame 1: out/f_0001.exr holds half-float colours (--half), rendering it again"),
            std::string::npos) << r.err;
  r = render(with({"--skip-existing", "--variance"}));
  EXPECT_NE(r.err.find("frame 2: out/f_0002.exr has no variance channels (--variance), rendering it again"),
            std::string::npos) << r.err;
  r = render(with({"--skip-existing", "--variance", "--resumable"}));
  EXPECT_NE(r.err.find("frame 2: out/f_0002.exr holds no exact sample sums (--resumable), rendering it again"),
            std::string::npos) << r.err;
  ASSERT_EQ(r.exit_code, 0) << r.err;

  // Rendered at 2 spp with exact sums, raised to 4.
  ASSERT_EQ(render(with({"--spp", "2", "--resumable"})).exit_code, 0);
  for (int k = 1; k <= 2; ++k) render_alone(k, frame("ref/f_", k, ".exr"), {"--spp", "4", "--resumable"});
  r = render(with({"--resume", "out/f_####.exr", "--spp", "4"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("frame 1: continuing out/f_0001.exr, which was rendered with tessera:spp 2, not 4"),
            std::string::npos) << r.err;
  for (int k = 1; k <= 2; ++k) expect_same_exr(frame("out/f_", k, ".exr"), frame("ref/f_", k, ".exr"));
  // Complete at 4 spp: files with exact sums count as complete without --resumable too.
  r = render(with({"--skip-existing", "--spp", "4"}));
  EXPECT_NE(r.err.find("0 rendered, 2 skipped"), std::string::npos) << r.err;
}

// Ctrl-C during a frame: that frame's partial EXR is written, no later frame is started, exit status 130.
TEST_F(CliSequence, InterruptStopsAfterThePartialFrame) {
  write_scene("shot/frame_0001.json", frame_scene(1));
  write_scene("shot/frame_0002.json", frame_scene(2, 200, 512));  // many seconds on one thread
  write_scene("shot/frame_0003.json", frame_scene(3));
  fs::create_directories(file("out"));
  const fs::path log = file("stderr.txt");
  const pid_t pid = ::fork();
  if (pid == 0) {
    start({"shot/frame_0001.json", "shot/frame_0002.json", "shot/frame_0003.json", "-o", "out/f_####.exr", "-q",
           "--threads", "1", "--tile", "8"},
          log);
    ::_exit(127);
  }
  // Once frame 2 has begun.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (read_text(log).find("frame 2 (2 of 3)") == std::string::npos && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  const std::string err = read_text(log);
  ASSERT_TRUE(WIFEXITED(status)) << err;
  EXPECT_EQ(WEXITSTATUS(status), 130) << err;
  EXPECT_FALSE(read_exr(file("out/f_0001.exr")).metadata.count("tessera:partial"));
  EXPECT_TRUE(read_exr(file("out/f_0002.exr")).metadata.count("tessera:partial")) << err;
  EXPECT_FALSE(fs::exists(file("out/f_0003.exr")));
  EXPECT_NE(err.find("the frames after frame 2 were not started"), std::string::npos) << err;
}

// Each bad input is refused with status 2 and a sentence naming the frame, file or option, before anything is
// rendered: the output folder stays empty.
TEST_F(CliSequence, BadInputsAreRefusedBeforeAnythingIsWritten) {
  write_frames(3);
  json missing_asset = frame_scene(2);
  missing_asset["objects"].push_back({{"type", "mesh"}, {"path", "assets/none.obj"}, {"material_name", "white"}});
  write_scene("broken/frame_0001.json", frame_scene(1));
  write_scene("broken/frame_0002.json", missing_asset);
  write("broken/frame_0003.json", "{\"integrator\": ");
  write_scene("lists/f_1.json", frame_scene(1));
  write_scene("lists/f_0001.json", frame_scene(1));
  write_scene("lists/scene.json", frame_scene(1));
  fs::create_directories(file("out"));
  const std::vector<std::string> three = {"shot/frame_0001.json", "shot/frame_0002.json", "shot/frame_0003.json"};
  const auto with = [&](std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"shot/frame_####.json", "--frames", "1-4", "-o", "out/f_####.exr"},
       "frame 4: shot/frame_0004.json does not exist"},
      {{"none/frame_*.json", "-o", "out/f_####.exr"}, "\"none/frame_*.json\" matches no file"},
      {{"shot/frame_####.json", "-o", "out/f_####.exr"}, "needs a frame range (--frames)"},
      {{"broken/frame_0001.json", "broken/frame_0002.json", "broken/frame_0003.json", "-o", "out/f_####.exr"},
       "frame 3: broken/frame_0003.json: invalid JSON"},
      {{"broken/frame_0001.json", "broken/frame_0002.json", "-o", "out/f_####.exr"},
       "frame 2: broken/frame_0002.json: objects[3].path"},
      {with(three, {"-o", "out/f.exr"}),
       "-o \"out/f.exr\" has no run of '#' for the frame number, and there are 3 frames"},
      {with(three, {"-o", "out/f_####.exr", "--preview", "out/p.png"}), "--preview \"out/p.png\" has no run of '#'"},
      {with(three, {"-o", "out/f_####.exr", "--crop", "0", "0", "4", "4"}), "--crop renders a part of one picture"},
      {with(three, {"-o", "out/f_####.exr", "--tile-budget", "2"}), "--tile-budget stops one render after N tiles"},
      {with(three, {"-o", "out/f_####.exr", "--resume", "shot/frame_0001.json"}),
       "--resume shot/frame_0001.json continues one render; with 3 frames it takes a pattern"},
      {with(three, {"-o", "out/f_####.exr", "--workers", "2", "--skip-existing"}),
       "--skip-existing and --resume render frames in this process"},
      {with(three, {"-o", "nowhere/f_####.exr"}), "the folder \"nowhere\" does not exist"},
      {{"shot/frame_0001.json", "-o", "out/f.exr", "--skip-existing", "--crop", "0", "0", "4", "4"},
       "--skip-existing judges whole frames"},
      {{"shot/frame_0001.json", "--frames", "1-3", "-o", "out/f_####.exr"}, "needs a scene pattern with a run of '#'"},
      {with(three, {"--frames", "1-3", "-o", "out/f_####.exr"}), "goes with one scene pattern"},
      {{"shot/frame_####.json", "--frames", "3-1", "-o", "out/f_####.exr"}, "ends before it starts"},
      {{"shot/frame_####.json", "--frames", "1-3,2", "-o", "out/f_####.exr"}, "names frame 2 twice"},
      {{"shot/frame_####.json", "--frames", "1-3x", "-o", "out/f_####.exr"}, "is not a frame number N, a range N-M"},
      {{"shot/frame_####.json", "--frames", "-1", "-o", "out/f_####.exr"}, "not negative"},
      {{"lists/f_1.json", "lists/f_0001.json", "-o", "out/f_####.exr"}, "frame 1 is named twice"},
      {{"lists/f_1.json", "lists/scene.json", "-o", "out/f_####.exr"}, "\"lists/scene.json\" has no frame number"},
  };
  for (const Case& c : cases) {
    const CliRun r = render(with(c.args, {"-q"}));
    EXPECT_EQ(r.exit_code, 2) << joined(c.args) << "\n" << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << joined(c.args) << "\n" << r.err;
    EXPECT_TRUE(files_in("out").empty()) << joined(c.args) << "\n" << r.err;
  }
}

}  // namespace
}  // namespace tessera
