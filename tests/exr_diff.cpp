#include "tests/exr_diff.h"

#include <OpenEXR/ImfAttribute.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStdIO.h>

#include <cstdint>
#include <cstring>
#include <map>

namespace tessera::testing {

const std::set<std::string>& attributes_allowed_to_differ() {
  static const std::set<std::string> names = {
      // storage
      "compression", "lineOrder", "tiles", "chunkCount", "type", "name", "version",
      // provenance
      "tessera:renderSeconds", "tessera:createdMs", "tessera:startedMs", "tessera:finishedMs", "tessera:job",
      "tessera:name", "tessera:workers", "tessera:scene", "tessera:tileSize", "tessera:sequence", "tessera:frame"};
  return names;
}

const std::set<std::string>& attributes_not_always_written() {
  static const std::set<std::string> names = {"tessera:areaSampling", "tessera:envSampling", "tessera:replicates",
                                              "tessera:targetError",  "tessera:minSpp",      "tessera:maxSpp",
                                              "tessera:errorFloor"};
  return names;
}

namespace {

// An attribute's value as the bytes OpenEXR writes for it.
std::string value_bytes(const Imf::Attribute& attr) {
  Imf::StdOSStream out;
  attr.writeValueTo(out, 2);
  return out.str();
}

size_t pixel_size(Imf::PixelType t) { return t == Imf::HALF ? 2 : 4; }

// Every channel's pixels as raw bytes in the channel's own type.
std::map<std::string, std::vector<char>> read_channels(Imf::InputFile& file) {
  const Imath::Box2i dw = file.header().dataWindow();
  const size_t w = size_t(dw.max.x - dw.min.x + 1), h = size_t(dw.max.y - dw.min.y + 1);
  std::map<std::string, std::vector<char>> out;
  Imf::FrameBuffer fb;
  for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
    const Imf::Channel& c = it.channel();
    const size_t xs = size_t(c.xSampling), ys = size_t(c.ySampling), size = pixel_size(c.type);
    std::vector<char>& buf = out[it.name()];
    buf.assign(((w + xs - 1) / xs) * ((h + ys - 1) / ys) * size, 0);
    // Base pointer shifted so that (x, y) of the data window lands at buf[((y - y0) / ys * row + (x - x0) / xs)].
    const size_t row = (w + xs - 1) / xs;
    char* base = buf.data() - (ptrdiff_t(dw.min.x) / ptrdiff_t(xs)) * ptrdiff_t(size) -
                 (ptrdiff_t(dw.min.y) / ptrdiff_t(ys)) * ptrdiff_t(row * size);
    fb.insert(it.name(), Imf::Slice(c.type, base, size, row * size, c.xSampling, c.ySampling));
  }
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return out;
}

}  // namespace

std::vector<std::string> exr_differences(const std::filesystem::path& a_path, const std::filesystem::path& b_path) {
  Imf::InputFile a(a_path.c_str()), b(b_path.c_str());
  std::vector<std::string> diffs;
  const auto& allowed = attributes_allowed_to_differ();
  for (auto [x, y, xname, yname] : {std::tuple{&a, &b, "A", "B"}, std::tuple{&b, &a, "B", "A"}})
    for (auto it = x->header().begin(); it != x->header().end(); ++it)
      if (!allowed.count(it.name()) && !attributes_not_always_written().count(it.name()) &&
          y->header().find(it.name()) == y->header().end())
        diffs.push_back(std::string("attribute ") + it.name() + " only in " + xname);
  for (auto it = a.header().begin(); it != a.header().end(); ++it) {
    if (allowed.count(it.name())) continue;
    const auto other = b.header().find(it.name());
    if (other == b.header().end()) continue;
    if (std::strcmp(it.attribute().typeName(), other.attribute().typeName()) != 0)
      diffs.push_back(std::string("attribute ") + it.name() + " has type " + it.attribute().typeName() + " vs " +
                      other.attribute().typeName());
    else if (value_bytes(it.attribute()) != value_bytes(other.attribute()))
      diffs.push_back(std::string("attribute ") + it.name() + " differs");
  }
  if (!diffs.empty()) return diffs;  // pixels are comparable only with the same windows and channels

  const auto pa = read_channels(a), pb = read_channels(b);
  const Imath::Box2i dw = a.header().dataWindow();
  const int w = dw.max.x - dw.min.x + 1;
  for (const auto& [name, bytes] : pa) {
    const std::vector<char>& other = pb.at(name);
    const size_t size = pixel_size(a.header().channels().find(name).channel().type);
    size_t differing = 0, first = 0;
    for (size_t i = 0; i < bytes.size() / size; ++i)
      if (std::memcmp(&bytes[i * size], &other[i * size], size) != 0 && differing++ == 0) first = i;
    if (differing > 0)
      diffs.push_back("channel " + name + ": " + std::to_string(differing) + " of " +
                      std::to_string(bytes.size() / size) + " values differ, first at pixel (" +
                      std::to_string(dw.min.x + int(first % size_t(w))) + ", " +
                      std::to_string(dw.min.y + int(first / size_t(w))) + ")");
  }
  return diffs;
}

}  // namespace tessera::testing
