#include "server/assembly.h"

#include "server/layer_preview.h"

#include "core/image/exr_uncompressed.h"

#include "failpoint/failpoint.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <vector>

namespace tessera::server {

namespace {

constexpr int32_t kExrFloat = 2;  // pixel type FLOAT in an EXR channel list (0 UINT, 1 HALF)

std::string describe(const PixelWindow& w) {
  return fmt::format("[{}, {}, {}, {})", w.x0, w.y0, w.x1, w.y1);
}

// What the first header of an EXR says about its layout, read straight from its bytes: a single-part file starts with
// magic and version, then attributes (name, type name, size, value) up to an empty name; "channels" is a chlist of
// (name, pixel type, pLinear, 3 reserved bytes, xSampling, ySampling) entries up to an empty name. Throws
// std::runtime_error for a header it cannot walk.
struct ExrLayout {
  struct Channel {
    std::string name;
    int32_t type = 0;
    bool subsampled = false;
  };
  int32_t version = 0;            // version field with its flags
  std::vector<Channel> channels;  // in file order (sorted by name)
  int compression = -1;
  int line_order = -1;
  std::optional<PixelWindow> data, display;
  size_t end = 0;  // offset just past the header (where the line offset table starts)
};

int32_t le32(std::string_view b, size_t pos) {
  if (pos + 4 > b.size()) throw std::runtime_error("header ends inside a number");
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | uint8_t(b[pos + size_t(i)]);
  return int32_t(v);
}

ExrLayout read_layout(std::string_view exr) {
  ExrLayout h;
  h.version = le32(exr, 4);
  size_t at = 8;
  const auto text = [&]() -> std::string_view {
    const size_t end = exr.find('\0', at);
    if (end == std::string_view::npos) throw std::runtime_error("header ends inside a name");
    const std::string_view s = exr.substr(at, end - at);
    at = end + 1;
    return s;
  };
  const auto box = [&](size_t pos) {  // box2i: xMin, yMin, xMax, yMax (inclusive)
    return PixelWindow{le32(exr, pos), le32(exr, pos + 4), le32(exr, pos + 8) + 1, le32(exr, pos + 12) + 1};
  };
  for (;;) {
    const std::string_view name = text();
    if (name.empty()) break;
    const std::string_view type = text();
    const int32_t size = le32(exr, at);
    at += 4;
    if (size < 0 || at + size_t(size) > exr.size()) throw std::runtime_error("header attribute overruns the file");
    const size_t value = at, end = at + size_t(size);
    if (name == "channels" && type == "chlist") {
      while (at < end) {
        const std::string_view channel = text();
        if (channel.empty()) break;
        h.channels.push_back({std::string(channel), le32(exr, at), le32(exr, at + 8) != 1 || le32(exr, at + 12) != 1});
        at += 16;
      }
    } else if (name == "compression" && type == "compression" && size == 1) {
      h.compression = uint8_t(exr[value]);
    } else if (name == "lineOrder" && type == "lineOrder" && size == 1) {
      h.line_order = uint8_t(exr[value]);
    } else if (name == "dataWindow" && type == "box2i" && size == 16) {
      h.data = box(value);
    } else if (name == "displayWindow" && type == "box2i" && size == 16) {
      h.display = box(value);
    }
    at = end;
  }
  h.end = at;
  return h;
}

// The channel problems a tile can have: R, G, B and the layers' channels must be there, float32 and full resolution.
std::optional<std::string> check_channels(const ExrLayout& h, const std::vector<std::string>& layers) {
  std::vector<std::string> names = {"R", "G", "B"};
  names.insert(names.end(), layers.begin(), layers.end());
  for (const std::string& wanted : names) {
    const auto it = std::find_if(h.channels.begin(), h.channels.end(), [&](const auto& c) { return c.name == wanted; });
    if (it == h.channels.end()) return std::string("channel ") + wanted + " is missing";
    if (it->type != kExrFloat) return std::string("channel ") + wanted + " is not float32";
    if (it->subsampled) return std::string("channel ") + wanted + " is subsampled";
  }
  return std::nullopt;
}

// What a tile's header must say before any of its pixels are decoded: one flat part (no deep data, no parts), at most
// kMaxTileChannels channels among which R, G and B are float32 at full resolution, the job's image as display window
// and the lease's tile as data window.
constexpr size_t kMaxTileChannels = 64;
std::optional<std::string> check_header(const ExrLayout& h, const PixelWindow& window, int width, int height,
                                        const std::vector<std::string>& layers) {
  constexpr int32_t kDeep = 0x800, kMultiPart = 0x1000;
  if ((h.version & 0xff) != 2) return "OpenEXR version " + std::to_string(h.version & 0xff) + " is not 2";
  if (h.version & (kDeep | kMultiPart)) return std::string("a tile must be one flat image, not deep or multi-part");
  if (h.channels.size() > kMaxTileChannels)
    return std::to_string(h.channels.size()) + " channels, more than the " + std::to_string(kMaxTileChannels) +
           " a tile may have";
  if (auto e = check_channels(h, layers)) return e;
  const PixelWindow full{0, 0, width, height};
  if (!h.display) return std::string("the header has no display window");
  if (!(*h.display == full)) return "display window is " + describe(*h.display) + ", expected " + describe(full);
  if (!h.data) return std::string("the header has no data window");
  if (!(*h.data == window))
    return "data window is " + describe(*h.data) + ", expected the tile's " + describe(window);
  return std::nullopt;
}

// A tile in the exact layout workers send (single-part scanline, uncompressed, channels B, G, R float32 and nothing
// else, one line per block, every block in place), decoded without OpenEXR's generic machinery: each line's three
// planes are interleaved into RGB. Anything else, or anything inconsistent, gives nothing and the caller decodes with
// OpenEXR (which also says what is wrong). The values are the file's bits, as OpenEXR would return them.
std::optional<ExrImage> decode_plain_tile(std::string_view exr, const ExrLayout& h) {
  constexpr int32_t kLongNames = 0x400;
  if ((h.version & 0xff) != 2 || (h.version & ~0xff & ~kLongNames) != 0) return std::nullopt;
  if (h.compression != 0 || !h.data || !h.display || h.data->empty() || h.channels.size() != 3) return std::nullopt;
  for (size_t c = 0; c < 3; ++c)
    if (h.channels[c].name != std::string(1, "BGR"[c]) || h.channels[c].type != kExrFloat || h.channels[c].subsampled)
      return std::nullopt;
  const PixelWindow w = *h.data;
  const size_t width = size_t(w.width()), height = size_t(w.height());
  if (width > 65536 || height > 65536) return std::nullopt;
  const size_t line_bytes = 3 * width * sizeof(float);
  if (h.end + 8 * height > exr.size()) return std::nullopt;
  ExrImage out;
  out.data_window = w;
  out.display_window = *h.display;
  out.pixels = Image::make(int(width), int(height));
  float* rgb = out.pixels.rgb.data();
  for (size_t line = 0; line < height; ++line) {
    uint64_t offset = 0;
    std::memcpy(&offset, exr.data() + h.end + 8 * line, 8);
    if (offset > exr.size() || exr.size() - offset < 8 + line_bytes) return std::nullopt;
    if (le32(exr, size_t(offset)) != w.y0 + int(line) || le32(exr, size_t(offset) + 4) != int32_t(line_bytes))
      return std::nullopt;
    const char* planes = exr.data() + offset + 8;  // B, G, R: width floats each
    for (size_t x = 0; x < width; ++x)
      for (size_t c = 0; c < 3; ++c)
        std::memcpy(rgb + 3 * (line * width + x) + c, planes + ((2 - c) * width + x) * sizeof(float), sizeof(float));
  }
  return out;
}

}  // namespace

TileCheck check_tile_exr(std::string_view bytes, const PixelWindow& window, int width, int height,
                         const std::vector<std::string>& layers) {
  TileCheck r;
  try {
    // The header is checked against the lease before a pixel is decoded, so that a decoder never allocates more than
    // the tile's window: a file claiming a larger image is refused from its header alone.
    if (bytes.size() < 8 || std::memcmp(bytes.data(), "\x76\x2f\x31\x01", 4) != 0) {
      r.error = "not a readable OpenEXR file: no OpenEXR magic number";
      return r;
    }
    const ExrLayout layout = read_layout(bytes);
    if (auto e = check_header(layout, window, width, height, layers)) {
      r.error = *e;
      return r;
    }
    // The layout workers send is decoded directly (most of an upload's decoding cost was OpenEXR's generic path);
    // any other file goes through OpenEXR, which also reads what the fast path refuses to guess at.
    std::optional<ExrImage> plain = decode_plain_tile(bytes, layout);
    ExrImage exr = plain ? std::move(*plain) : decode_exr(bytes);
    if (!(exr.data_window == window) || exr.pixels.width != window.width() || exr.pixels.height != window.height()) {
      r.error = "pixel block does not match the data window";
      return r;
    }
    for (size_t i = 0; i < exr.pixels.rgb.size(); ++i)
      if (!std::isfinite(exr.pixels.rgb[i])) {
        const size_t p = i / 3;
        r.error = "pixel (" + std::to_string(window.x0 + int(p % size_t(window.width()))) + ", " +
                  std::to_string(window.y0 + int(p / size_t(window.width()))) + ") is not finite";
        return r;
      }
    std::map<std::string, std::vector<float>> kept;
    for (const std::string& name : layers) {
      const auto it = exr.pixels.extra.find(name);
      if (it == exr.pixels.extra.end()) {
        r.error = "channel " + name + " is missing";
        return r;
      }
      kept.emplace(name, std::move(it->second));
    }
    exr.pixels.extra = std::move(kept);
    r.pixels = std::move(exr.pixels);
  } catch (const std::exception& e) {
    r.error = std::string("not a readable OpenEXR file: ") + e.what();
  }
  return r;
}

std::string_view tile_bytes(const Image& tile, const std::vector<std::string>& layers, std::string& buffer) {
  const std::string_view rgb = tile_bytes(tile);
  if (layers.empty()) return rgb;
  buffer.assign(rgb);
  for (const std::string& name : layers) {
    const std::vector<float>& ch = tile.extra.at(name);
    buffer.append(reinterpret_cast<const char*>(ch.data()), ch.size() * sizeof(float));
  }
  return buffer;
}

Image tile_from_bytes(std::string_view bytes, int width, int height, const std::vector<std::string>& layers) {
  Image img = Image::make(width, height);
  const size_t rgb = img.rgb.size() * sizeof(float), plane = size_t(width) * size_t(height) * sizeof(float);
  if (bytes.size() != rgb + layers.size() * plane)
    throw std::invalid_argument("stored tile has " + std::to_string(bytes.size()) + " bytes, expected " +
                                std::to_string(rgb + layers.size() * plane) + " for " + std::to_string(width) + "x" +
                                std::to_string(height) + " float32 RGB and " + std::to_string(layers.size()) +
                                " layer channel(s)");
  std::memcpy(img.rgb.data(), bytes.data(), rgb);
  for (size_t c = 0; c < layers.size(); ++c) {
    std::vector<float>& ch = img.extra[layers[c]];
    ch.resize(size_t(width) * size_t(height));
    std::memcpy(ch.data(), bytes.data() + rgb + c * plane, plane);
  }
  return img;
}

namespace {

// Generations of every JobImage in the process, so that no two images' generations coincide.
std::atomic<uint64_t> g_generations{0};

}  // namespace

JobImage::JobImage(int width, int height, std::vector<std::string> layers)
    : width_(width), height_(height), layers_(std::move(layers)), generation_(++g_generations) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("job image needs a positive size");
}

uint64_t JobImage::generation() {
  std::lock_guard lock(mu_);
  return generation_;
}

void JobImage::allocate() {
  std::lock_guard lock(mu_);
  allocate_locked();
}

void JobImage::allocate_locked() {
  if (!image_.rgb.empty()) return;
  image_ = Image::make(width_, height_);
  for (const std::string& name : layers_) image_.extra[name].assign(size_t(width_) * size_t(height_), 0.f);
}

void JobImage::paste(const Image& tile, const PixelWindow& w) {
  if (!PixelWindow{0, 0, width_, height_}.contains(w) || w.empty() || tile.width != w.width() || tile.height != w.height())
    throw std::invalid_argument("tile " + describe(w) + " does not fit the " + std::to_string(width_) + "x" +
                                std::to_string(height_) + " image");
  TESSERA_FAIL_POINT("assembly.paste");
  std::lock_guard lock(mu_);
  allocate_locked();
  generation_ = ++g_generations;
  const size_t row_floats = 3 * size_t(w.width());
  for (int y = 0; y < w.height(); ++y)
    std::memcpy(&image_.rgb[3 * (size_t(w.y0 + y) * size_t(width_) + size_t(w.x0))], &tile.rgb[size_t(y) * row_floats],
                row_floats * sizeof(float));
  for (const std::string& name : layers_) {
    const auto it = tile.extra.find(name);
    if (it == tile.extra.end()) continue;  // a tile of a job without layers
    std::vector<float>& ch = image_.extra[name];
    for (int y = 0; y < w.height(); ++y)
      std::memcpy(&ch[size_t(w.y0 + y) * size_t(width_) + size_t(w.x0)], &it->second[size_t(y) * size_t(w.width())],
                  size_t(w.width()) * sizeof(float));
  }
}

std::vector<uint8_t> JobImage::preview_png() {
  std::lock_guard lock(mu_);
  return server::preview_png(image_.rgb.empty() ? nullptr : &image_, width_, height_);
}

std::vector<uint8_t> JobImage::layer_preview_png(Layer layer) {
  std::lock_guard lock(mu_);
  allocate_locked();
  const Image shown = layer_display(image_, layer);
  return server::preview_png(&shown, width_, height_);
}

void JobImage::write_exr(const std::filesystem::path& file, const std::map<std::string, std::string>& metadata,
                         const std::map<std::string, std::vector<uint32_t>>& uint_channels) {
  TESSERA_FAIL_POINT("assembly.write_result");
  std::lock_guard lock(mu_);
  allocate_locked();
  try {
    const Imath::Box2i window(Imath::V2i(0, 0), Imath::V2i(width_ - 1, height_ - 1));
    Imf::Header header(window, window);
    // Uncompressed: on a 3840x2160 float frame ZIP costs 7.4 s to save 5% (rendered noise barely compresses), while
    // the whole file is written in 0.2 s, so assembly stays a small fraction of rendering.
    header.compression() = Imf::NO_COMPRESSION;
    for (const auto& [key, value] : metadata) header.insert(key, Imf::StringAttribute(value));
    Imf::FrameBuffer fb;
    const char* const rgb[] = {"R", "G", "B"};
    const char* const base = reinterpret_cast<const char*>(image_.rgb.data());
    for (size_t c = 0; c < 3; ++c) {
      header.channels().insert(rgb[c], Imf::Channel(Imf::FLOAT));
      fb.insert(rgb[c], Imf::Slice::Make(Imf::FLOAT, base + c * sizeof(float), window, 3 * sizeof(float),
                                         3 * sizeof(float) * size_t(width_)));
    }
    const size_t pixels = size_t(width_) * size_t(height_);
    for (const auto& [name, values] : image_.extra) {
      header.channels().insert(name, Imf::Channel(Imf::FLOAT));
      fb.insert(name, Imf::Slice::Make(Imf::FLOAT, values.data(), window));
    }
    for (const auto& [name, values] : uint_channels) {
      if (values.size() != pixels || header.channels().findChannel(name))
        throw std::runtime_error("channel " + name + " does not fit the image");
      header.channels().insert(name, Imf::Channel(Imf::UINT));
      fb.insert(name, Imf::Slice::Make(Imf::UINT, values.data(), window));
    }
    // Written directly (OpenEXR's OutputFile would hand each of the image's lines to its thread pool and wait).
    {
      std::ofstream bytes(file, std::ios::binary | std::ios::trunc);
      if (!bytes) throw std::runtime_error("cannot create the file");
      Imf::StdOFStream os(bytes, file.c_str());
      if (write_uncompressed_exr(os, header, fb)) {
        bytes.flush();  // a failure to write the last bytes is seen here, not lost in the stream's destructor
        if (!bytes) throw std::runtime_error("writing failed");
        return;
      }
    }
    Imf::OutputFile out(file.c_str(), header, 0);
    out.setFrameBuffer(fb);
    out.writePixels(height_);
  } catch (const std::exception& e) {
    throw ImageError("cannot write EXR " + file.string() + ": " + e.what());
  }
}

void JobImage::release() {
  std::lock_guard lock(mu_);
  image_ = Image{};
}

}  // namespace tessera::server
