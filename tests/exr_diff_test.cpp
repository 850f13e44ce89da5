// The comparer behind every "bitwise identical" claim of the farm and deploy tests: each kind of difference it must
// catch (one bit of any channel, a channel's pixel type, a missing or extra channel, either window, metadata that must
// match) is caught, and what may differ (compression, render time, job provenance) is not reported.
#include "tests/exr_diff.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace tessera::testing {
namespace {

namespace fs = std::filesystem;

// What to write: a 5x3 data window inside an 8x6 display window, R, G, B, variance.R and samples as floats.
struct Spec {
  Imath::Box2i display{{0, 0}, {7, 5}};
  Imath::Box2i data{{1, 2}, {5, 4}};
  std::map<std::string, Imf::PixelType> channels = {{"R", Imf::FLOAT},          {"G", Imf::FLOAT},
                                                    {"B", Imf::FLOAT},          {"variance.R", Imf::FLOAT},
                                                    {"samples", Imf::FLOAT}};
  Imf::Compression compression = Imf::NO_COMPRESSION;
  std::map<std::string, std::string> strings = {{"tessera:sceneHash", "ab12"}, {"tessera:spp", "16"},
                                                {"tessera:seed", "0"},         {"tessera:renderSeconds", "1.5"},
                                                {"tessera:job", "j1"}};
  std::map<std::string, int> ints;
  float aspect = 1.f;
  std::string flip_channel;  // one bit of this channel's pixel flip_index is flipped
  size_t flip_index = 0;
};

class ExrDiff : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tessera_exr_diff_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const Spec& s) {
    const fs::path p = dir_ / name;
    Imf::Header h(s.display, s.data, s.aspect);
    h.compression() = s.compression;
    for (const auto& [k, v] : s.strings) h.insert(k, Imf::StringAttribute(v));
    for (const auto& [k, v] : s.ints) h.insert(k, Imf::IntAttribute(v));
    const size_t w = size_t(s.data.max.x - s.data.min.x + 1), ht = size_t(s.data.max.y - s.data.min.y + 1);
    std::map<std::string, std::vector<float>> f;
    std::map<std::string, std::vector<half>> hv;
    Imf::FrameBuffer fb;
    int c = 0;
    for (const auto& [name, type] : s.channels) {
      h.channels().insert(name, Imf::Channel(type));
      std::vector<float> v(w * ht);
      for (size_t i = 0; i < v.size(); ++i) v[i] = 0.1f * float(i) + float(c);
      ++c;
      if (name == s.flip_channel) {
        uint32_t bits;
        std::memcpy(&bits, &v[s.flip_index], 4);
        bits ^= type == Imf::HALF ? 0x2000u : 1u;  // the last bit that survives the channel's type
        std::memcpy(&v[s.flip_index], &bits, 4);
      }
      char* base;
      size_t size;
      if (type == Imf::HALF) {
        auto& buf = hv[name];
        for (float x : v) buf.push_back(half(x));
        base = reinterpret_cast<char*>(buf.data());
        size = sizeof(half);
      } else {
        f[name] = v;
        base = reinterpret_cast<char*>(f[name].data());
        size = sizeof(float);
      }
      base -= (ptrdiff_t(s.data.min.x) + ptrdiff_t(s.data.min.y) * ptrdiff_t(w)) * ptrdiff_t(size);
      fb.insert(name, Imf::Slice(type, base, size, size * w));
    }
    Imf::OutputFile out(p.c_str(), h);
    out.setFrameBuffer(fb);
    out.writePixels(int(ht));
    return p;
  }

  // The differences between the default file and one written from the default spec changed by `change`.
  std::vector<std::string> diff(const std::function<void(Spec&)>& change) {
    Spec s;
    change(s);
    return exr_differences(write("a.exr", Spec{}), write("b.exr", s));
  }
  static std::string join(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += x + "; ";
    return s;
  }
  void expect_caught(const std::function<void(Spec&)>& change, const std::string& expected) {
    const auto d = diff(change);
    EXPECT_NE(std::string::npos, join(d).find(expected)) << "expected '" << expected << "' in: " << join(d);
  }

  fs::path dir_;
};

TEST_F(ExrDiff, IdenticalFilesHaveNoDifference) { EXPECT_TRUE(diff([](Spec&) {}).empty()); }

TEST_F(ExrDiff, StorageAndProvenanceMayDiffer) {
  const auto d = diff([](Spec& s) {
    s.compression = Imf::ZIP_COMPRESSION;
    s.strings["tessera:renderSeconds"] = "2.25";
    s.strings.erase("tessera:job");
    s.strings["tessera:workers"] = "w1,w2";
  });
  EXPECT_TRUE(d.empty()) << join(d);
}

TEST_F(ExrDiff, OneBitOfAnyChannelIsCaught) {
  for (const std::string channel : {"R", "G", "B", "variance.R", "samples"})
    for (size_t index : {size_t(0), size_t(7), size_t(14)}) {
      std::string expected = "channel ";
      expected.append(channel).append(": 1 of 15 values differ");
      expect_caught([&](Spec& s) { s.flip_channel = channel, s.flip_index = index; }, expected);
    }
}

TEST_F(ExrDiff, OneBitOfAHalfChannelIsCaught) {
  const auto half_spec = [](Spec& s) { s.channels["G"] = Imf::HALF; };
  const fs::path a = write("a.exr", [&] { Spec s; half_spec(s); return s; }());
  Spec b;
  half_spec(b);
  b.flip_channel = "G";
  b.flip_index = 3;
  EXPECT_NE(std::string::npos, join(exr_differences(a, write("b.exr", b))).find("channel G: 1 of 15"));
}

TEST_F(ExrDiff, ChannelTypesAndListsAreCompared) {
  expect_caught([](Spec& s) { s.channels["samples"] = Imf::HALF; }, "attribute channels differs");
  expect_caught([](Spec& s) { s.channels["samples"] = Imf::UINT; }, "attribute channels differs");
  expect_caught([](Spec& s) { s.channels.erase("variance.R"); }, "attribute channels differs");
  expect_caught([](Spec& s) { s.channels["A"] = Imf::FLOAT; }, "attribute channels differs");
}

TEST_F(ExrDiff, WindowsAreCompared) {
  expect_caught([](Spec& s) { s.data = {{2, 2}, {6, 4}}; }, "attribute dataWindow differs");
  expect_caught([](Spec& s) { s.display = {{0, 0}, {8, 5}}; }, "attribute displayWindow differs");
  expect_caught([](Spec& s) { s.aspect = 2.f; }, "attribute pixelAspectRatio differs");
}

TEST_F(ExrDiff, MetadataThatMustMatchIsCompared) {
  expect_caught([](Spec& s) { s.strings["tessera:sceneHash"] = "ab13"; }, "attribute tessera:sceneHash differs");
  expect_caught([](Spec& s) { s.strings["tessera:seed"] = "42"; }, "attribute tessera:seed differs");
  expect_caught([](Spec& s) { s.strings.erase("tessera:spp"); }, "attribute tessera:spp only in A");
  expect_caught([](Spec& s) { s.strings["tessera:version"] = "0.1.0"; }, "attribute tessera:version only in B");
}

// Sampling options: written by `tessera render`, not by the farm's merge; compared when both files have them.
TEST_F(ExrDiff, OptionsSomeWritersOmitAreComparedWhenBothHaveThem) {
  const auto with = [this](const std::string& name, const std::string& area) {
    Spec s;
    if (!area.empty()) s.strings["tessera:areaSampling"] = area;
    return write(name, s);
  };
  EXPECT_TRUE(exr_differences(with("a.exr", "area"), with("b.exr", "")).empty());
  EXPECT_TRUE(exr_differences(with("a.exr", "area"), with("b.exr", "area")).empty());
  EXPECT_EQ(std::vector<std::string>{"attribute tessera:areaSampling differs"},
            exr_differences(with("a.exr", "area"), with("b.exr", "solid_angle")));
}

TEST_F(ExrDiff, AttributeTypesAreCompared) {
  expect_caught(
      [](Spec& s) {
        s.strings.erase("tessera:seed");
        s.ints["tessera:seed"] = 0;
      },
      "attribute tessera:seed has type string vs int");
}

}  // namespace
}  // namespace tessera::testing
