// Unit tests of cli/frame_list.h: frame ranges, frame patterns and lists of scene files, and every refusal.
#include "cli/frame_list.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <stdexcept>

namespace tessera::cli {
namespace {

namespace fs = std::filesystem;
using Numbers = std::vector<int64_t>;

// The message of the std::invalid_argument that `f` throws ("" when it throws nothing).
template <class F>
std::string refusal(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// A fresh folder per test, removed afterwards, with empty scene files made on demand.
class FrameList : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) / ("tessera_frames_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Creates the file `name` in the folder and returns its path.
  std::string touch(const std::string& name) const {
    const fs::path p = dir_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << "{}";
    return p.string();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

TEST(FrameRange, SingleNumbersRangesAndSteps) {
  EXPECT_EQ(parse_frame_range("7"), (Numbers{7}));
  EXPECT_EQ(parse_frame_range("0"), (Numbers{0}));
  EXPECT_EQ(parse_frame_range("1-5"), (Numbers{1, 2, 3, 4, 5}));
  EXPECT_EQ(parse_frame_range("3-3"), (Numbers{3}));
  EXPECT_EQ(parse_frame_range("1-10x3"), (Numbers{1, 4, 7, 10}));
  EXPECT_EQ(parse_frame_range("1-240x2").size(), 120u);
  EXPECT_EQ(parse_frame_range("1-240x2").back(), 239);
  EXPECT_EQ(parse_frame_range("1,5,10-12"), (Numbers{1, 5, 10, 11, 12}));
  // Sorted, whatever the order of the items; leading zeros are allowed.
  EXPECT_EQ(parse_frame_range("300,1-3,007"), (Numbers{1, 2, 3, 7, 300}));
  EXPECT_EQ(parse_frame_range("1-240x2,300").back(), 300);
}

TEST(FrameRange, RefusesMalformedEmptyNegativeAndDuplicateRanges) {
  const auto refused = [](const std::string& range) { return refusal([&] { parse_frame_range(range); }); };
  EXPECT_NE(refused("").find("empty"), std::string::npos);
  for (const char* bad : {"a", "1-", "-", "1-x", "1-5x", "1-5x2x3", "1..5", "1-5y", "1 - 5", " 1", "1-5x2-3", "0x1"}) {
    const std::string why = refused(bad);
    EXPECT_FALSE(why.empty()) << bad;
    EXPECT_NE(why.find(bad), std::string::npos) << bad << ": " << why;
  }
  EXPECT_NE(refused("1,,3").find("an item is empty"), std::string::npos);
  EXPECT_NE(refused("1,").find("an item is empty"), std::string::npos);
  EXPECT_NE(refused(",1").find("an item is empty"), std::string::npos);
  EXPECT_NE(refused("10-1").find("\"10-1\" is empty: it ends before it starts"), std::string::npos);
  EXPECT_NE(refused("-5").find("not negative"), std::string::npos);
  EXPECT_NE(refused("1,-5-3").find("not negative"), std::string::npos);
  EXPECT_NE(refused("5--3").find("not negative"), std::string::npos);
  EXPECT_NE(refused("1-5x-1").find("not negative"), std::string::npos);
  EXPECT_NE(refused("1-5x0").find("the step must be at least 1"), std::string::npos);
  EXPECT_NE(refused("5x2").find("a step goes with a range"), std::string::npos);
  EXPECT_NE(refused("1-10,5").find("names frame 5 twice"), std::string::npos);
  EXPECT_NE(refused("3,3").find("names frame 3 twice"), std::string::npos);
  EXPECT_NE(refused("99999999999999999999").find("is too large"), std::string::npos);
  EXPECT_NE(refused("0-9999999").find("more than 1000000 frames"), std::string::npos);
  EXPECT_NE(refused("0-600000,700000-1300000").find("more than 1000000 frames"), std::string::npos);
  EXPECT_EQ(parse_frame_range("0-999999").size(), kMaxFrames);
}

TEST(FrameOutput, ReplacesTheLastRunOfHashes) {
  EXPECT_EQ(frame_output("out/frame_####.exr", 7, 3), fs::path("out/frame_0007.exr"));
  EXPECT_EQ(frame_output("out/frame_####.exr", 0, 3), fs::path("out/frame_0000.exr"));
  EXPECT_EQ(frame_output("out/frame_#.exr", 12, 3), fs::path("out/frame_12.exr"));
  // More digits than the run holds: the number is written whole.
  EXPECT_EQ(frame_output("f_###.exr", 12345, 2), fs::path("f_12345.exr"));
  // Only the last run: an earlier '#' is part of the name.
  EXPECT_EQ(frame_output("take#2/f_##.exr", 3, 2), fs::path("take#2/f_03.exr"));
  EXPECT_EQ(frame_output("shot_##/f.exr", 4, 2), fs::path("shot_04/f.exr"));
  // Without '#': the pattern itself, for one frame only.
  EXPECT_EQ(frame_output("out.exr", 5, 1), fs::path("out.exr"));
  const std::string why = refusal([] { frame_output("out/beauty.exr", 5, 3); });
  EXPECT_NE(why.find("\"out/beauty.exr\" has no run of '#'"), std::string::npos) << why;
  EXPECT_NE(why.find("3 frames (e.g. out/beauty_####.exr)"), std::string::npos) << why;
  EXPECT_NE(refusal([] { frame_output("f_####.exr", -1, 2); }).find("not negative"), std::string::npos);
}

TEST_F(FrameList, PatternAndRange) {
  for (int n = 1; n <= 9; ++n) touch("shot/frame_000" + std::to_string(n) + ".json");
  const std::vector<FrameFile> frames = expand_frames({path("shot/frame_####.json")}, "1-9x2");
  ASSERT_EQ(frames.size(), 5u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].number, int64_t(1 + 2 * i));
    EXPECT_EQ(frames[i].scene, fs::path(path("shot/frame_000" + std::to_string(1 + 2 * i) + ".json")));
  }
  // A one-frame range is a sequence of one frame.
  EXPECT_EQ(expand_frames({path("shot/frame_####.json")}, "4").size(), 1u);
}

TEST_F(FrameList, PatternRefusals) {
  for (int n = 1; n <= 3; ++n) touch("shot/frame_000" + std::to_string(n) + ".json");
  touch("a.json");
  const std::string pattern = path("shot/frame_####.json");
  // A missing frame names its number and file (and how many more are missing).
  std::string why = refusal([&] { expand_frames({pattern}, "1-5"); });
  EXPECT_NE(why.find("frame 4: " + path("shot/frame_0004.json") + " does not exist (2 of the 5 frames are missing)"),
            std::string::npos) << why;
  why = refusal([&] { expand_frames({pattern}, "1-3,17"); });
  EXPECT_NE(why.find("frame 17: " + path("shot/frame_0017.json") + " does not exist"), std::string::npos) << why;
  EXPECT_EQ(why.find("frames are missing"), std::string::npos) << why;
  // A folder where a frame's scene should be.
  fs::create_directories(path("shot/frame_0004.json"));
  why = refusal([&] { expand_frames({pattern}, "4"); });
  EXPECT_NE(why.find("frame 4: " + path("shot/frame_0004.json") + " is not a scene file"), std::string::npos) << why;
  // A range with a scene file that has no '#', or with several files.
  why = refusal([&] { expand_frames({path("a.json")}, "1-3"); });
  EXPECT_NE(why.find("needs a scene pattern with a run of '#'"), std::string::npos) << why;
  EXPECT_NE(why.find(path("a.json") + "\" has none"), std::string::npos) << why;
  why = refusal([&] { expand_frames({path("shot/frame_0001.json"), path("shot/frame_0002.json")}, "1-2"); });
  EXPECT_NE(why.find("not with 2 scene files"), std::string::npos) << why;
  // The range's own refusals.
  EXPECT_NE(refusal([&] { expand_frames({pattern}, "3-1"); }).find("ends before it starts"), std::string::npos);
  EXPECT_NE(refusal([&] { expand_frames({pattern}, "1-3,2"); }).find("names frame 2 twice"), std::string::npos);
  EXPECT_NE(refusal([&] { expand_frames({pattern}, "-1"); }).find("not negative"), std::string::npos);
  EXPECT_NE(refusal([&] { expand_frames({pattern}, "1-x"); }).find("is not a frame number"), std::string::npos);
  // A pattern with no range is a file name that does not exist.
  why = refusal([&] { expand_frames({pattern}, ""); });
  EXPECT_NE(why.find("needs a frame range (--frames)"), std::string::npos) << why;
  EXPECT_NE(refusal([] { expand_frames({}, ""); }).find("no scene file given"), std::string::npos);
}

TEST_F(FrameList, ListOfFiles) {
  // As a shell's glob expansion gives them (sorted by name, not number), in several folders and paddings.
  const std::vector<FrameFile> frames =
      expand_frames({touch("shot/frame_10.json"), touch("shot/frame_2.json"), touch("b/take2_frame_0003.json")}, "");
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].number, 2);  // the last run of digits in the name without its extension
  EXPECT_EQ(frames[0].scene, fs::path(path("shot/frame_2.json")));
  EXPECT_EQ(frames[1].number, 2 + 1);
  EXPECT_EQ(frames[1].scene, fs::path(path("b/take2_frame_0003.json")));
  EXPECT_EQ(frames[2].number, 10);
  // One file: frame 0 when its name has no digits.
  const std::vector<FrameFile> one = expand_frames({touch("scene.json")}, "");
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].number, 0);
  EXPECT_EQ(expand_frames({touch("take_42.json")}, "")[0].number, 42);
}

TEST_F(FrameList, ListRefusals) {
  const std::string a = touch("shot/frame_1.json"), b = touch("shot/frame_0001.json"), c = touch("other.json");
  std::string why = refusal([&] { expand_frames({a, b}, ""); });
  EXPECT_NE(why.find("frame 1 is named twice: "), std::string::npos) << why;
  EXPECT_NE(why.find(a), std::string::npos) << why;
  EXPECT_NE(why.find(b), std::string::npos) << why;
  why = refusal([&] { expand_frames({a, c}, ""); });
  EXPECT_NE(why.find("\"" + c + "\" has no frame number"), std::string::npos) << why;
  why = refusal([&] { expand_frames({a, path("shot/frame_2.json")}, ""); });
  EXPECT_NE(why.find("\"" + path("shot/frame_2.json") + "\" does not exist"), std::string::npos) << why;
  // An unmatched glob reaches the command as it was typed.
  why = refusal([&] { expand_frames({path("none/frame_*.json")}, ""); });
  EXPECT_NE(why.find("\"" + path("none/frame_*.json") + "\" matches no file"), std::string::npos) << why;
  why = refusal([&] { expand_frames({a, path("shot")}, ""); });
  EXPECT_NE(why.find("\"" + path("shot") + "\" is not a scene file"), std::string::npos) << why;
  why = refusal([&] { expand_frames({a, path("shot/frame_99999999999999999999.json")}, ""); });
  EXPECT_FALSE(why.empty());
}

TEST_F(FrameList, TooLargeFrameNumberInAName) {
  const std::string big = touch("f_99999999999999999999.json");
  const std::string why = refusal([&] { expand_frames({touch("f_1.json"), big}, ""); });
  EXPECT_NE(why.find("is too large"), std::string::npos) << why;
}

}  // namespace
}  // namespace tessera::cli
