#include "server/assembly.h"

#include "failpoint/failpoint.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace tessera::server {

namespace {

std::string describe(const PixelWindow& w) {
  return fmt::format("[{}, {}, {}, {})", w.x0, w.y0, w.x1, w.y1);
}

// Checks the channel list before the pixels are decoded: R, G and B must be there and be 32-bit floats.
std::optional<std::string> check_channels(const std::filesystem::path& file) {
  Imf::InputFile in(file.c_str());
  const Imf::ChannelList& ch = in.header().channels();
  for (const char* name : {"R", "G", "B"}) {
    const Imf::Channel* c = ch.findChannel(name);
    if (!c) return std::string("channel ") + name + " is missing";
    if (c->type != Imf::FLOAT) return std::string("channel ") + name + " is not float32";
    if (c->xSampling != 1 || c->ySampling != 1) return std::string("channel ") + name + " is subsampled";
  }
  return std::nullopt;
}

}  // namespace

TileCheck check_tile_exr(const std::filesystem::path& file, const PixelWindow& window, int width, int height) {
  TileCheck r;
  try {
    if (auto e = check_channels(file)) {
      r.error = *e;
      return r;
    }
    ExrImage exr = read_exr(file);
    const PixelWindow full{0, 0, width, height};
    if (!(exr.display_window == full)) {
      r.error = "display window is " + describe(exr.display_window) + ", expected " + describe(full);
      return r;
    }
    if (!(exr.data_window == window)) {
      r.error = "data window is " + describe(exr.data_window) + ", expected the tile's " + describe(window);
      return r;
    }
    if (exr.pixels.width != window.width() || exr.pixels.height != window.height()) {
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
    exr.pixels.extra.clear();
    r.pixels = std::move(exr.pixels);
  } catch (const std::exception& e) {
    // The reader names the scratch file; the uploader only needs the reason.
    std::string why = e.what();
    for (size_t at; (at = why.find(file.string())) != std::string::npos;) why.replace(at, file.string().size(), "upload");
    r.error = "not a readable OpenEXR file: " + why;
  }
  return r;
}

std::string_view tile_bytes(const Image& tile) {
  return std::string_view(reinterpret_cast<const char*>(tile.rgb.data()), tile.rgb.size() * sizeof(float));
}

Image tile_from_bytes(std::string_view bytes, int width, int height) {
  Image img = Image::make(width, height);
  if (bytes.size() != img.rgb.size() * sizeof(float))
    throw std::invalid_argument("stored tile has " + std::to_string(bytes.size()) + " bytes, expected " +
                                std::to_string(img.rgb.size() * sizeof(float)) + " for " + std::to_string(width) + "x" +
                                std::to_string(height) + " float32 RGB");
  std::memcpy(img.rgb.data(), bytes.data(), bytes.size());
  return img;
}

JobImage::JobImage(int width, int height) : width_(width), height_(height) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("job image needs a positive size");
}

void JobImage::allocate_locked() {
  if (image_.rgb.empty()) image_ = Image::make(width_, height_);
}

void JobImage::paste(const Image& tile, const PixelWindow& w) {
  if (!PixelWindow{0, 0, width_, height_}.contains(w) || w.empty() || tile.width != w.width() || tile.height != w.height())
    throw std::invalid_argument("tile " + describe(w) + " does not fit the " + std::to_string(width_) + "x" +
                                std::to_string(height_) + " image");
  TESSERA_FAIL_POINT("assembly.paste");
  std::lock_guard lock(mu_);
  allocate_locked();
  const size_t row_floats = 3 * size_t(w.width());
  for (int y = 0; y < w.height(); ++y)
    std::memcpy(&image_.rgb[3 * (size_t(w.y0 + y) * size_t(width_) + size_t(w.x0))], &tile.rgb[size_t(y) * row_floats],
                row_floats * sizeof(float));
}

std::vector<uint8_t> JobImage::preview_png() {
  std::lock_guard lock(mu_);
  allocate_locked();
  return encode_png_srgb(image_);
}

void JobImage::write_exr(const std::filesystem::path& path, const std::map<std::string, std::string>& metadata,
                         std::map<std::string, std::vector<uint32_t>> uint_channels) {
  TESSERA_FAIL_POINT("assembly.write_result");
  std::lock_guard lock(mu_);
  allocate_locked();
  image_.uint_extra = std::move(uint_channels);
  ExrWriteOptions o;
  o.display_window = PixelWindow{0, 0, width_, height_};
  o.data_window = o.display_window;
  o.metadata = metadata;
  // Uncompressed: on a 3840x2160 float frame ZIP costs 7.4 s to save 5% (rendered noise barely compresses), while
  // the whole file is written in 0.2 s, so assembly stays a small fraction of rendering.
  o.compression = ExrCompression::kNone;
  try {
    tessera::write_exr(path, image_, o);
  } catch (...) {
    image_.uint_extra.clear();
    throw;
  }
  image_.uint_extra.clear();
}

void JobImage::release() {
  std::lock_guard lock(mu_);
  image_ = Image{};
}

}  // namespace tessera::server
