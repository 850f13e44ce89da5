// read_exr's OpenEXRCore path (core/image/exr_core_decode.h) against OpenEXR's C++ InputFile on the same bytes: every
// value bitwise the same, for every half bit pattern, random floats and NaN payloads, UINT channels, every
// compression (those OpenEXRCore does not take go to the C++ library), windows off the origin, partial last blocks,
// the banded multi-threaded decode of large images, and damaged files.
#include "core/image/exr_core_decode.h"
#include "core/image/exr_layout.h"
#include "core/image/image.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <Imath/half.h>
#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <string>
#include <vector>

namespace tessera {
namespace exr_core_decode_test {  // named: the test files share translation units in a unity build

struct Layout {
  PixelWindow window;
  Imf::Compression compression = Imf::ZIP_COMPRESSION;
  Imf::PixelType colour = Imf::HALF;
  bool grey = false;    // Y instead of R,G,B
  bool extras = true;   // a FLOAT, a HALF and a UINT channel beside the colour
};

// Raw channel data of a test file: 32-bit words per pixel, half bit patterns in the low 16 bits of HALF channels.
using Planes = std::map<std::string, std::vector<uint32_t>>;

uint32_t next(uint32_t& s) { return s = s * 1664525u + 1013904223u; }

// Fills every channel: HALF channels walk through all 65536 bit patterns (offset per channel), FLOAT ones take random
// words (NaNs with payloads and infinities included), UINT ones random words.
Planes make_planes(const Layout& l) {
  const size_t n = size_t(l.window.width()) * size_t(l.window.height());
  Planes p;
  uint32_t seed = 12345;
  const auto fill = [&](const std::string& name, Imf::PixelType t, uint32_t offset) {
    std::vector<uint32_t>& v = p[name];
    v.resize(n);
    for (size_t i = 0; i < n; ++i) v[i] = t == Imf::HALF ? uint32_t((i * 7 + offset) & 0xffff) : next(seed);
  };
  if (l.grey) {
    fill("Y", l.colour, 0);
  } else {
    fill("R", l.colour, 0);
    fill("G", l.colour, 21845);
    fill("B", l.colour, 43690);
  }
  if (l.extras) {
    fill("depth", Imf::FLOAT, 0);
    fill("alpha", Imf::HALF, 999);
    fill("id", Imf::UINT, 0);
  }
  return p;
}

Imf::PixelType type_of(const Layout& l, const std::string& name) {
  if (name == "depth") return Imf::FLOAT;
  if (name == "alpha") return Imf::HALF;
  if (name == "id") return Imf::UINT;
  return l.colour;
}

// The file OpenEXR's C++ library writes for these planes (scanline; tiled 16x16 when `tiled`).
std::string write_file(const Layout& l, const Planes& planes, bool tiled = false) {
  const Imath::Box2i dw({l.window.x0, l.window.y0}, {l.window.x1 - 1, l.window.y1 - 1});
  Imf::Header h(Imath::Box2i({0, 0}, {31, 31}), dw);
  h.compression() = l.compression;
  std::map<std::string, std::vector<half>> halves;
  Imf::FrameBuffer fb;
  const size_t w = size_t(l.window.width());
  for (const auto& [name, words] : planes) {
    const Imf::PixelType t = type_of(l, name);
    h.channels().insert(name, Imf::Channel(t));
    if (t == Imf::HALF) {
      std::vector<half>& hv = halves[name];
      for (uint32_t word : words) {
        half bits;
        bits.setBits(uint16_t(word));
        hv.push_back(bits);
      }
      fb.insert(name, Imf::Slice::Make(t, hv.data(), dw, sizeof(half), sizeof(half) * w));
    } else {
      fb.insert(name, Imf::Slice::Make(t, words.data(), dw, 4, 4 * w));
    }
  }
  exr_io::MemoryOStream os("(test)");
  if (tiled) {
    h.setTileDescription(Imf::TileDescription(16, 16, Imf::ONE_LEVEL));
    Imf::TiledOutputFile out(os, h, 0);
    out.setFrameBuffer(fb);
    out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
  } else {
    Imf::OutputFile out(os, h, 0);
    out.setFrameBuffer(fb);
    out.writePixels(l.window.height());
  }
  const std::vector<uint8_t> bytes = os.take();
  return std::string(bytes.begin(), bytes.end());
}

// What OpenEXR's C++ InputFile reads from the file: each channel as 32-bit words (HALF and FLOAT as float, UINT as is).
Planes read_with_cxx(const std::string& bytes) {
  exr_io::MemoryIStream is(bytes, "(test)");
  Imf::InputFile in(is, 0);
  const Imath::Box2i dw = in.header().dataWindow();
  const size_t w = size_t(dw.max.x - dw.min.x + 1), h = size_t(dw.max.y - dw.min.y + 1);
  Planes p;
  Imf::FrameBuffer fb;
  for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) {
    std::vector<uint32_t>& v = p[c.name()];
    v.assign(w * h, 0xdeadbeef);
    fb.insert(c.name(), Imf::Slice::Make(c.channel().type == Imf::UINT ? Imf::UINT : Imf::FLOAT, v.data(), dw, 4, 4 * w));
  }
  in.setFrameBuffer(fb);
  in.readPixels(dw.min.y, dw.max.y);
  return p;
}

std::vector<uint32_t> words(const std::vector<float>& v) {
  std::vector<uint32_t> out(v.size());
  std::memcpy(out.data(), v.data(), v.size() * sizeof(float));
  return out;
}

// decode_exr's pixels as planes of words, in the layout read_with_cxx gives.
Planes read_with_decode_exr(const std::string& bytes, bool grey) {
  const ExrImage img = decode_exr(bytes);
  Planes p;
  const size_t n = size_t(img.pixels.width) * size_t(img.pixels.height);
  const std::vector<uint32_t> rgb = words(img.pixels.rgb);
  const std::vector<std::string> names = grey ? std::vector<std::string>{"Y"} : std::vector<std::string>{"R", "G", "B"};
  for (size_t c = 0; c < names.size(); ++c) {
    std::vector<uint32_t>& v = p[names[c]];
    for (size_t i = 0; i < n; ++i) v.push_back(rgb[3 * i + c]);
  }
  if (grey)
    for (size_t i = 0; i < n; ++i) {
      EXPECT_EQ(rgb[3 * i + 1], rgb[3 * i]);
      EXPECT_EQ(rgb[3 * i + 2], rgb[3 * i]);
    }
  for (const auto& [name, values] : img.pixels.extra) p[name] = words(values);
  for (const auto& [name, values] : img.pixels.uint_extra) p[name] = values;
  return p;
}

void expect_same_planes(const Planes& a, const Planes& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (const auto& [name, values] : a) {
    ASSERT_TRUE(b.count(name)) << what << ": " << name;
    const std::vector<uint32_t>& other = b.at(name);
    ASSERT_EQ(values.size(), other.size()) << what << ": " << name;
    size_t differ = 0, first = values.size();
    for (size_t i = 0; i < values.size(); ++i)
      if (values[i] != other[i] && differ++ == 0) first = i;
    EXPECT_EQ(differ, 0u) << what << ": channel " << name << " differs in " << differ << " values, first at " << first
                          << " (" << std::hex << values[first] << " against " << other[std::min(first, other.size() - 1)]
                          << ")";
  }
}

std::vector<exr_core::ChannelTarget> rgb_targets(Image& img) {
  const size_t stride = 3 * sizeof(float);
  std::vector<exr_core::ChannelTarget> t;
  for (size_t c = 0; c < 3; ++c)
    t.push_back({std::string(1, "RGB"[c]), reinterpret_cast<std::byte*>(img.rgb.data() + c), false, stride,
                 stride * size_t(img.width)});
  return t;
}

// Whether OpenEXRCore decodes the file itself (every channel of it), rather than leaving it to the C++ library.
bool core_takes(const std::string& bytes, const Layout& l, const Planes& planes) {
  std::map<std::string, std::vector<uint32_t>> out;
  std::vector<exr_core::ChannelTarget> targets;
  for (const auto& [name, words] : planes) {
    out[name].resize(words.size());
    targets.push_back({name, reinterpret_cast<std::byte*>(out[name].data()), type_of(l, name) == Imf::UINT, 4,
                       4 * size_t(l.window.width())});
  }
  return exr_core::decode_scanlines(bytes, l.window, targets);
}

TEST(ExrCoreDecode, GivesTheCxxLibrarysValuesForEveryCompressionAndType) {
  const std::vector<Imf::Compression> compressions = {Imf::NO_COMPRESSION, Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
                                                      Imf::RLE_COMPRESSION, Imf::PIZ_COMPRESSION};
  const std::vector<Layout> layouts = {
      {{-7, 13, 249, 272}, Imf::ZIP_COMPRESSION, Imf::HALF, false, true},  // 256x259: every half pattern, last block short
      {{0, 0, 1, 1}, Imf::ZIP_COMPRESSION, Imf::FLOAT, false, true},
      {{3, 5, 40, 22}, Imf::ZIP_COMPRESSION, Imf::FLOAT, true, true},      // grey
      {{0, 0, 64, 64}, Imf::ZIP_COMPRESSION, Imf::FLOAT, false, false},
  };
  for (Layout l : layouts)
    for (const Imf::Compression c : compressions) {
      l.compression = c;
      const Planes planes = make_planes(l);
      const std::string bytes = write_file(l, planes);
      const std::string what = "compression " + std::to_string(int(c)) + ", " + std::to_string(l.window.width()) + "x" +
                               std::to_string(l.window.height()) + (l.grey ? " grey" : "");
      expect_same_planes(read_with_cxx(bytes), read_with_decode_exr(bytes, l.grey), what);
      const bool for_core = c == Imf::NO_COMPRESSION || c == Imf::ZIPS_COMPRESSION || c == Imf::ZIP_COMPRESSION;
      EXPECT_EQ(core_takes(bytes, l, planes), for_core) << what;
    }
}

TEST(ExrCoreDecode, LargeImagesDecodeInBandsToTheSameValues) {
  // 700x530 ZIP: 34 blocks of 16 lines, over the size where blocks are decoded by several tasks.
  Layout l{{-5, 2, 695, 532}, Imf::ZIP_COMPRESSION, Imf::FLOAT, false, true};
  const Planes planes = make_planes(l);
  const std::string bytes = write_file(l, planes);
  expect_same_planes(read_with_cxx(bytes), read_with_decode_exr(bytes, false), "700x530 float ZIP");
  EXPECT_TRUE(core_takes(bytes, l, planes));
  l.compression = Imf::NO_COMPRESSION;  // 530 one-line blocks
  l.colour = Imf::HALF;
  const Planes half_planes = make_planes(l);
  const std::string plain = write_file(l, half_planes);
  expect_same_planes(read_with_cxx(plain), read_with_decode_exr(plain, false), "700x530 half uncompressed");
  EXPECT_TRUE(core_takes(plain, l, half_planes));
}

TEST(ExrCoreDecode, DeclinesWhatItLeavesToTheCxxLibrary) {
  Layout l{{0, 0, 40, 40}, Imf::ZIP_COMPRESSION, Imf::HALF, false, false};
  const Planes planes = make_planes(l);
  Image img = Image::make(40, 40);
  const auto targets = rgb_targets(img);
  EXPECT_TRUE(exr_core::decode_scanlines(write_file(l, planes), l.window, targets));
  // Another data window, a channel the file lacks, a UINT target for a HALF channel.
  EXPECT_FALSE(exr_core::decode_scanlines(write_file(l, planes), {0, 0, 40, 39}, targets));
  std::vector<exr_core::ChannelTarget> missing = targets;
  missing[0].name = "X";
  EXPECT_FALSE(exr_core::decode_scanlines(write_file(l, planes), l.window, missing));
  std::vector<exr_core::ChannelTarget> as_uint = targets;
  as_uint[1].uint = true;
  EXPECT_FALSE(exr_core::decode_scanlines(write_file(l, planes), l.window, as_uint));
  // Tiled files and other compressions; not an EXR at all.
  EXPECT_FALSE(exr_core::decode_scanlines(write_file(l, planes, true), l.window, targets));
  l.compression = Imf::PIZ_COMPRESSION;
  EXPECT_FALSE(exr_core::decode_scanlines(write_file(l, planes), l.window, targets));
  EXPECT_FALSE(exr_core::decode_scanlines("not an EXR", l.window, targets));
  // read_exr still reads the tiled file, through the C++ library.
  l.compression = Imf::ZIP_COMPRESSION;
  const std::string tiled = write_file(l, planes, true);
  expect_same_planes(read_with_cxx(tiled), read_with_decode_exr(tiled, false), "tiled");
}

TEST(ExrCoreDecode, DamagedFilesGetTheCxxLibrarysVerdict) {
  Layout l{{0, 0, 64, 64}, Imf::ZIP_COMPRESSION, Imf::FLOAT, false, true};
  const std::string good = write_file(l, make_planes(l));
  Image img = Image::make(64, 64);
  const auto targets = rgb_targets(img);
  // Cut inside the last block, and a block's compressed bytes overwritten (past the header and offset table).
  const std::string cut = good.substr(0, good.size() - 100);
  EXPECT_FALSE(exr_core::decode_scanlines(cut, l.window, targets));
  EXPECT_THROW(decode_exr(cut), ImageError);
  std::string garbled = good;
  for (size_t i = garbled.size() / 2; i < garbled.size() / 2 + 64; ++i) garbled[i] = char(0x5a);
  EXPECT_FALSE(exr_core::decode_scanlines(garbled, l.window, targets));
  bool cxx_throws = false;
  try {
    read_with_cxx(garbled);
  } catch (const std::exception&) {
    cxx_throws = true;
  }
  if (cxx_throws) {
    EXPECT_THROW(decode_exr(garbled), ImageError);
  }
}

}  // namespace exr_core_decode_test
}  // namespace tessera
