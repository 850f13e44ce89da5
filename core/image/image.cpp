#include "core/image/image.h"

#include "core/image/exr_attribute_sizes.h"
#include "core/image/exr_core_decode.h"
#include "core/image/exr_layout.h"
#include "core/image/exr_uncompressed.h"
#include "core/image/exr_zip.h"
#include "core/util/file_io.h"
#include "core/util/zeroed_buffer.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTileDescription.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfVersion.h>
#include <Imath/half.h>
#include <png.h>
#include <tbb/global_control.h>


#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <mutex>
#include <span>
#include <string_view>
#include <system_error>

namespace tessera {
namespace {

constexpr int64_t kMaxSide = 65536;  // Largest data window width or height read_exr accepts.

// Header attributes that lay out the file rather than describe the picture: never metadata.
constexpr std::array<std::string_view, 14> kLayoutAttributes = {
    "channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio", "screenWindowCenter",
    "screenWindowWidth", "tiles", "name", "type", "version", "chunkCount", "maxSamplesPerPixel"};

// Standard attributes (ImfStandardAttributes.h) whose type is not string: writing one as a string would make
// other readers' typed accessors throw.
constexpr std::array<std::string_view, 24> kTypedStandardAttributes = {
    "chromaticities", "whiteLuminance", "adoptedNeutral", "xDensity", "utcOffset", "longitude", "latitude",
    "altitude", "focus", "expTime", "aperture", "isoSpeed", "envmap", "keyCode", "timeCode", "framesPerSecond",
    "multiView", "worldToCamera", "worldToNDC", "deepImageState", "originalDataWindow", "dwaCompressionLevel",
    "idManifest", "preview"};

bool is_one_of(std::string_view name, std::span<const std::string_view> names) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

// A data window over the caller's bound (ExrReadOptions::max_pixels), before with_context names the file.
struct DataWindowTooLarge : std::runtime_error {
  DataWindowTooLarge(int64_t width, int64_t height, uint64_t limit)
      : std::runtime_error("data window " + std::to_string(width) + "x" + std::to_string(height) + " = " +
                           std::to_string(width * height) + " pixels is over the limit of " + std::to_string(limit)),
        width(width), height(height), limit(limit) {}
  int64_t width, height;
  uint64_t limit;
};

// Runs f, turning any exception into an ImageError whose message starts with context. The *_impl functions below
// throw whatever they meet (their own std::runtime_error reasons, OpenEXR errors, bad_alloc); the public functions
// wrap them with this, so every error leaves as an ImageError naming the file (where there is one), or as an
// ExrTooLarge.
template <class F>
auto with_context(const std::string& context, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const DataWindowTooLarge& e) {
    throw ExrTooLarge(context + ": " + e.what(), e.width, e.height, e.limit);
  } catch (const std::exception& e) {
    throw ImageError(context + ": " + e.what());
  }
}

PixelWindow to_window(const Imath::Box2i& b) { return {b.min.x, b.min.y, b.max.x + 1, b.max.y + 1}; }

Imath::Box2i to_box(const PixelWindow& w) { return Imath::Box2i({w.x0, w.y0}, {w.x1 - 1, w.y1 - 1}); }

// Throws unless img.rgb holds exactly 3 * width * height floats.
void check_rgb_shape(const Image& img) {
  if (img.width < 0 || img.height < 0)
    throw std::runtime_error("negative image size " + std::to_string(img.width) + "x" + std::to_string(img.height));
  const size_t expected = 3 * size_t(img.width) * size_t(img.height);
  if (img.rgb.size() != expected)
    throw std::runtime_error("image " + std::to_string(img.width) + "x" + std::to_string(img.height) + " has " +
                             std::to_string(img.rgb.size()) + " colour values, expected " + std::to_string(expected));
}

}  // namespace

namespace exr_layout {

// Each line block is compressed on its own, so the file's bytes do not depend on the count; OpenEXR's pool is
// resized only when the count changes.
int compression_threads() {
  static std::mutex mu;
  static int pool = 0;
  const int want = int(std::max<size_t>(1, tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
  std::lock_guard lock(mu);
  if (want != pool) {
    Imf::setGlobalThreadCount(want);
    pool = want;
  }
  return want;
}

PixelWindow data_window(const Image& img, const ExrWriteOptions& opt, bool band) {
  check_rgb_shape(img);
  if (img.width == 0 || img.height == 0) throw std::runtime_error("an EXR cannot hold an empty image");
  const PixelWindow data = opt.data_window.empty() ? PixelWindow{0, 0, img.width, img.height} : opt.data_window;
  if (data.width() != img.width || (!band && data.height() != img.height))
    throw std::runtime_error("data window size " + std::to_string(data.width()) + "x" + std::to_string(data.height()) +
                             " differs from the image size " + std::to_string(img.width) + "x" +
                             std::to_string(img.height));
  return data;
}

Imf::Header header(const Image& img, const ExrWriteOptions& opt, const PixelWindow& data) {
  const PixelWindow display = opt.display_window.empty() ? data : opt.display_window;
  Imf::Header h(to_box(display), to_box(data));
  switch (opt.compression) {
    case ExrCompression::kZip:
      h.compression() = Imf::ZIP_COMPRESSION;
      // Rendered 32-bit floats barely compress at any level: level 1 writes within 0.3% of the default (4)'s bytes
      // for less work (docs/performance.md). Half colours do compress, 5-9% better at 4.
      if (!opt.half) h.zipCompressionLevel() = 1;
      break;
    case ExrCompression::kPiz: h.compression() = Imf::PIZ_COMPRESSION; break;
    case ExrCompression::kNone: h.compression() = Imf::NO_COMPRESSION; break;
  }
  for (const auto& [key, value] : opt.metadata) {
    if (is_one_of(key, kLayoutAttributes) || is_one_of(key, kTypedStandardAttributes))
      throw std::runtime_error("metadata key \"" + key + "\" is a standard EXR attribute and cannot be a string");
    h.insert(key, Imf::StringAttribute(value));
  }
  const Imf::PixelType rgb_type = opt.half ? Imf::HALF : Imf::FLOAT;
  for (const char* name : {"R", "G", "B"}) h.channels().insert(name, Imf::Channel(rgb_type));
  if (opt.write_extra) {
    const auto add_channel = [&](const std::string& name, Imf::PixelType type) {
      if (name == "R" || name == "G" || name == "B" || h.channels().findChannel(name))
        throw std::runtime_error("extra channel \"" + name + "\" collides with another channel");
      h.channels().insert(name, Imf::Channel(type));
    };
    for (const auto& entry : img.extra) add_channel(entry.first, Imf::FLOAT);
    for (const auto& entry : img.uint_extra) add_channel(entry.first, Imf::UINT);
  }
  return h;
}

Frame frame(const Image& img, const ExrWriteOptions& opt, const PixelWindow& rows) {
  Frame f;
  const Imath::Box2i box = to_box(rows);
  // OutputFile does not convert between pixel types, so half output needs a half copy of the colours.
  if (opt.half) {
    f.rgb_half.resize(img.rgb.size());
    std::transform(img.rgb.begin(), img.rgb.end(), f.rgb_half.begin(), [](float v) { return half(v); });
  }
  const Imf::PixelType rgb_type = opt.half ? Imf::HALF : Imf::FLOAT;
  const char* const rgb_base = opt.half ? reinterpret_cast<const char*>(f.rgb_half.data())
                                        : reinterpret_cast<const char*>(img.rgb.data());
  const size_t value_size = opt.half ? sizeof(half) : sizeof(float);
  const char* const rgb_names[] = {"R", "G", "B"};
  for (size_t i = 0; i < 3; ++i)
    f.buffer.insert(rgb_names[i], Imf::Slice::Make(rgb_type, rgb_base + i * value_size, box, 3 * value_size,
                                                   3 * value_size * size_t(img.width)));
  if (opt.write_extra) {
    check_extra_sizes(img, opt);
    for (const auto& [name, values] : img.extra) f.buffer.insert(name, Imf::Slice::Make(Imf::FLOAT, values.data(), box));
    for (const auto& [name, values] : img.uint_extra)
      f.buffer.insert(name, Imf::Slice::Make(Imf::UINT, values.data(), box));
  }
  return f;
}

void check_extra_sizes(const Image& img, const ExrWriteOptions& opt) {
  if (!opt.write_extra) return;
  const size_t expected = size_t(img.width) * size_t(img.height);
  const auto check = [&](const std::string& name, size_t size) {
    if (size != expected)
      throw std::runtime_error("extra channel \"" + name + "\" has " + std::to_string(size) + " values, expected " +
                               std::to_string(expected));
  };
  for (const auto& [name, values] : img.extra) check(name, values.size());
  for (const auto& [name, values] : img.uint_extra) check(name, values.size());
}

}  // namespace exr_layout

namespace {

using exr_io::MemoryIStream;
using exr_io::MemoryOStream;
using exr_io::quoted;

// What decoding a file whose header passed check_exr_header costs, as far as the header tells.
struct ExrDecodeCost {
  Imf::Compression compression = Imf::NO_COMPRESSION;
  bool tiled = false;
  int64_t pixels = 0;  // in the data window
};

// Reads the first header from is (positioned just after the magic number and version field) of a file of `size`
// bytes and rejects what read_exr cannot or should not load (a data window over max_pixels among it), before OpenEXR
// sizes any table or buffer from the header; tells what decoding will cost.
struct ExrHeaderCheck {
  ExrDecodeCost cost;
  Imf::Header header;  // as read (sanity-checked)
};
ExrHeaderCheck check_exr_header(Imf::IStream& is, int version, uint64_t size, uint64_t max_pixels) {
  if (Imf::getVersion(version) != Imf::EXR_VERSION || !Imf::supportsFlags(Imf::getFlags(version)))
    throw std::runtime_error("unsupported OpenEXR version field " + std::to_string(version));
  if (Imf::isNonImage(version)) throw std::runtime_error("deep OpenEXR files are not supported");
  const uint64_t start = is.tellg();
  check_attribute_sizes(is, size, Imf::isMultiPart(version));
  is.seekg(start);
  Imf::Header header;
  int flags = version;
  header.readFrom(is, flags);  // may set the long-names flag
  header.sanityCheck(Imf::isTiled(flags), Imf::isMultiPart(flags));

  // sanityCheck has ensured non-empty windows with corners inside (-INT_MAX/2, INT_MAX/2), so neither the sizes
  // below nor the half-open bounds (max + 1) overflow.
  const Imath::Box2i& dw = header.dataWindow();
  const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
  const int64_t h = int64_t(dw.max.y) - dw.min.y + 1;
  const uint64_t limit = std::min(max_pixels, kMaxExrPixels);
  if (uint64_t(w) * uint64_t(h) > limit) throw DataWindowTooLarge(w, h, limit);
  if (w > kMaxSide || h > kMaxSide)
    throw std::runtime_error("data window " + std::to_string(w) + "x" + std::to_string(h) +
                             " is outside the supported size (at most " + std::to_string(kMaxSide) + " per side)");
  if (header.hasTileDescription()) {
    const Imf::TileDescription& t = header.tileDescription();
    if (t.xSize > kMaxSide || t.ySize > kMaxSide || uint64_t(t.xSize) * t.ySize > kMaxExrPixels)
      throw std::runtime_error("tile size " + std::to_string(t.xSize) + "x" + std::to_string(t.ySize) +
                               " is outside the supported size");
  }
  return {{header.compression(), header.hasTileDescription(), w * h}, header};
}

// OpenEXR decodes a scanline file's line blocks as tasks on its pool. Blocks of one line (no compression, RLE, ZIPS)
// of a small image cost less to decode than to hand over: on the 2-core VM an uncompressed 64x64 tile took 454 us
// with the pool and 216 us without, 256x256 3.3 ms against 2.5 ms, 512x512 7.9 ms against 9.7 ms; ZIP-compressed
// (16-line blocks) 64x64 203 us against 289 us, 512x512 7.4 ms against 13.5 ms.
int decode_threads(const ExrDecodeCost& cost) {
  const bool one_line_blocks = cost.compression == Imf::NO_COMPRESSION || cost.compression == Imf::RLE_COMPRESSION ||
                               cost.compression == Imf::ZIPS_COMPRESSION;
  return !cost.tiled && one_line_blocks && cost.pixels < 512 * 512 ? 0 : exr_layout::compression_threads();
}

// The header's string, int and double attributes as text, leaving out the layout attributes.
std::map<std::string, std::string> read_metadata(const Imf::Header& header) {
  std::map<std::string, std::string> out;
  for (auto it = header.begin(); it != header.end(); ++it) {
    if (is_one_of(it.name(), kLayoutAttributes)) continue;
    const Imf::Attribute* a = &it.attribute();
    if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(a)) {
      out[it.name()] = s->value();
    } else if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(a)) {
      out[it.name()] = std::to_string(i->value());
    } else if (const auto* d = dynamic_cast<const Imf::DoubleAttribute*>(a)) {
      char buf[32];
      const auto res = std::to_chars(buf, buf + sizeof buf, d->value());  // shortest text that reads back exactly
      out[it.name()] = std::string(buf, res.ptr);
    }
  }
  return out;
}

// Reads the colour of a luminance/chroma file (Y, RY, BY) through OpenEXR's RGBA interface, which undoes the
// chroma subsampling.
void read_luminance_chroma(Imf::IStream& is, const Imath::Box2i& dw, Image& img) {
  is.seekg(0);
  Imf::RgbaInputFile in(is);
  std::vector<Imf::Rgba> buf(size_t(img.width) * size_t(img.height));
  // The frame buffer base is addressed by absolute pixel coordinates (the same arithmetic as Imf::Slice::Make).
  const intptr_t origin_offset = (intptr_t(dw.min.x) + intptr_t(dw.min.y) * img.width) * intptr_t(sizeof(Imf::Rgba));
  in.setFrameBuffer(reinterpret_cast<Imf::Rgba*>(reinterpret_cast<intptr_t>(buf.data()) - origin_offset), 1,
                    size_t(img.width));
  in.readPixels(dw.min.y, dw.max.y);
  for (size_t i = 0; i < buf.size(); ++i) {
    img.rgb[3 * i] = buf[i].r;
    img.rgb[3 * i + 1] = buf[i].g;
    img.rgb[3 * i + 2] = buf[i].b;
  }
}

// The version field after the magic number (the first `got` of 8 bytes read), so that short and foreign data get a
// plain message.
int exr_version(const char (&start)[8], std::streamsize got) {
  if (got < 4 || !Imf::isImfMagic(start)) throw std::runtime_error("not an OpenEXR file (no magic number)");
  if (got < 8) throw std::runtime_error("file ends inside the version field");
  return int(uint32_t(uint8_t(start[4])) | uint32_t(uint8_t(start[5])) << 8 | uint32_t(uint8_t(start[6])) << 16 |
             uint32_t(uint8_t(start[7])) << 24);
}

// How a file's channels map onto an ExrImage: its colour model and where each channel read goes.
enum class Colour { kRgb, kGrey, kLuminanceChroma };
struct DecodePlan {
  ExrImage out;  // windows, metadata, pixels sized (and extra channels created) for the data window
  Colour colour = Colour::kRgb;
  std::vector<exr_core::ChannelTarget> targets;  // R,G,B (or Y) into out.pixels.rgb, then every extra channel
  // Every channel read is full resolution, and HALF, FLOAT or UINT.
  bool plain = true;
};

// Lays out `plan` for a file with this header (plan.out's buffers stay where they are while plan lives); extra
// channels are left out when colour_only.
void plan_decode(const Imf::Header& header, DecodePlan& plan, bool colour_only) {
  const Imath::Box2i dw = header.dataWindow();
  ExrImage& out = plan.out;
  out.data_window = to_window(dw);
  out.display_window = to_window(header.displayWindow());
  out.metadata = read_metadata(header);
  Image& img = out.pixels;
  img = Image::make(out.data_window.width(), out.data_window.height());

  const Imf::ChannelList& channels = header.channels();
  const auto full_resolution = [&](const char* name) {
    const Imf::Channel* c = channels.findChannel(name);
    return c && c->xSampling == 1 && c->ySampling == 1;
  };
  std::vector<std::string_view> colour_channels;
  if (channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B")) {
    if (!full_resolution("R") || !full_resolution("G") || !full_resolution("B"))
      throw std::runtime_error("subsampled R,G,B channels are not supported");
    plan.colour = Colour::kRgb;
    colour_channels = {"R", "G", "B"};
  } else if (channels.findChannel("Y") && channels.findChannel("RY") && channels.findChannel("BY")) {
    plan.colour = Colour::kLuminanceChroma;
    plan.plain = false;
    colour_channels = {"Y", "RY", "BY"};
  } else if (full_resolution("Y")) {
    plan.colour = Colour::kGrey;
    colour_channels = {"Y"};
  } else {
    std::string names;
    for (auto c = channels.begin(); c != channels.end(); ++c) names += std::string(names.empty() ? "" : ",") + c.name();
    throw std::runtime_error("no R,G,B or full-resolution Y channels (channels: " + (names.empty() ? "none" : names) +
                             ")");
  }
  const size_t row_pixels = size_t(img.width);
  constexpr size_t kPixelStride = 3 * sizeof(float);
  const auto is_float = [](Imf::PixelType t) { return t == Imf::HALF || t == Imf::FLOAT; };
  if (plan.colour != Colour::kLuminanceChroma) {
    for (size_t i = 0; i < colour_channels.size(); ++i) {
      const Imf::Channel* c = channels.findChannel(std::string(colour_channels[i]));
      plan.plain = plan.plain && is_float(c->type);
      plan.targets.push_back({std::string(colour_channels[i]), reinterpret_cast<std::byte*>(img.rgb.data() + i), false,
                              kPixelStride, kPixelStride * row_pixels});
    }
  }
  for (auto c = channels.begin(); c != channels.end() && !colour_only; ++c) {
    if (is_one_of(c.name(), colour_channels) || c.channel().xSampling != 1 || c.channel().ySampling != 1) continue;
    plan.plain = plan.plain && (is_float(c.channel().type) || c.channel().type == Imf::UINT);
    std::byte* first = nullptr;
    const bool uint = c.channel().type == Imf::UINT;
    if (uint) {
      std::vector<uint32_t>& values = img.uint_extra[c.name()];
      values.assign(row_pixels * size_t(img.height), 0U);
      first = reinterpret_cast<std::byte*>(values.data());
    } else {
      std::vector<float>& values = img.extra[c.name()];
      values.assign(row_pixels * size_t(img.height), 0.f);
      first = reinterpret_cast<std::byte*>(values.data());
    }
    plan.targets.push_back({c.name(), first, uint, 4, 4 * row_pixels});
  }
}

// Fills in the colour a plan's targets do not read directly: G and B of a grey file, all three of a luminance/chroma
// one (read from `stream` again).
void finish_colour(DecodePlan& plan, Imf::IStream& stream) {
  Image& img = plan.out.pixels;
  if (plan.colour == Colour::kGrey) {
    for (size_t i = 0; i < img.rgb.size(); i += 3) img.rgb[i + 1] = img.rgb[i + 2] = img.rgb[i];
  } else if (plan.colour == Colour::kLuminanceChroma) {
    read_luminance_chroma(stream, to_box(plan.out.data_window), img);
  }
}

// Reads the EXR from stream, whose header passed `check`, with OpenEXR's C++ library.
ExrImage read_exr_stream(Imf::IStream& stream, const ExrHeaderCheck& check, bool colour_only) {
  stream.seekg(0);

  Imf::InputFile in(stream, decode_threads(check.cost));
  if (!in.isComplete()) throw std::runtime_error("file is incomplete (truncated or damaged)");
  DecodePlan plan;
  plan_decode(in.header(), plan, colour_only);
  const Imath::Box2i dw = in.header().dataWindow();
  Imf::FrameBuffer fb;
  for (const exr_core::ChannelTarget& t : plan.targets) {
    // Slice::Make takes the data window's first pixel and addresses the rest by absolute pixel coordinates.
    fb.insert(t.name, Imf::Slice::Make(t.uint ? Imf::UINT : Imf::FLOAT, t.first, dw, t.pixel_stride, t.line_stride));
  }
  if (fb.begin() != fb.end()) {
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
  }
  finish_colour(plan, stream);
  return std::move(plan.out);
}

// Reads an EXR held in memory: OpenEXRCore decodes the common files (single-part scanline, none/ZIPS/ZIP, R,G,B or
// Y and extra channels at full resolution, exr_core_decode.h), OpenEXR's C++ library the rest and whatever OpenEXRCore
// declines, so its verdict and messages stand for damaged files. Both give the same values (ExrCoreDecode tests).
ExrImage decode_exr_impl(std::string_view bytes, const ExrReadOptions& options) {
  char start[8] = {};
  const size_t got = std::min<size_t>(8, bytes.size());
  std::memcpy(start, bytes.data(), got);
  const int version = exr_version(start, std::streamsize(got));
  MemoryIStream stream(bytes, "(memory)");
  stream.seekg(8);
  const ExrHeaderCheck check = check_exr_header(stream, version, bytes.size(), options.max_pixels);
  // The pixels are allocated only once OpenEXRCore has found every block in the file.
  const std::unique_ptr<exr_core::ScanlineDecoder> core =
      check.cost.tiled || Imf::isMultiPart(version)
          ? nullptr
          : exr_core::ScanlineDecoder::open(bytes, to_window(check.header.dataWindow()));
  if (core) {
    DecodePlan plan;
    plan_decode(check.header, plan, options.colour_only);
    if (plan.plain && core->decode(plan.targets)) {
      finish_colour(plan, stream);
      return std::move(plan.out);
    }
  }
  return read_exr_stream(stream, check, options.colour_only);
}

// Files up to this size are read into memory and decoded as decode_exr_impl does; larger ones are streamed through
// OpenEXR's C++ library, so that a huge file is not held twice.
constexpr std::uintmax_t kInMemoryFileBytes = std::uintmax_t(256) << 20;

ExrImage read_exr_impl(const std::filesystem::path& path, const ExrReadOptions& options) {
  std::error_code size_error;
  const std::uintmax_t size = std::filesystem::file_size(path, size_error);
  // A file whose size cannot be told (missing, unreadable, not a regular file) is read to find out why.
  if (size_error || size <= kInMemoryFileBytes) return decode_exr_impl(read_file_bytes(path), options);
  errno = 0;
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error(errno != 0 ? errno_text(errno) : "cannot open file");
  char start[8] = {};
  file.read(start, 8);
  if (file.bad()) throw std::runtime_error(errno != 0 ? errno_text(errno) : "read error");
  const int version = exr_version(start, file.gcount());
  Imf::StdIFStream stream(file, path.c_str());
  return read_exr_stream(stream, check_exr_header(stream, version, uint64_t(size), options.max_pixels),
                         options.colour_only);
}

ExrHeader read_exr_header_impl(const std::filesystem::path& path) {
  errno = 0;
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error(errno != 0 ? errno_text(errno) : "cannot open file");
  const std::uintmax_t size = std::filesystem::file_size(path);
  char start[8] = {};
  file.read(start, 8);
  if (file.bad()) throw std::runtime_error(errno != 0 ? errno_text(errno) : "read error");
  const int version = exr_version(start, file.gcount());
  Imf::StdIFStream stream(file, path.c_str());
  const ExrHeaderCheck check = check_exr_header(stream, version, uint64_t(size), kMaxExrPixels);
  ExrHeader out;
  out.data_window = to_window(check.header.dataWindow());
  out.display_window = to_window(check.header.displayWindow());
  out.metadata = read_metadata(check.header);
  for (auto it = check.header.channels().begin(); it != check.header.channels().end(); ++it)
    out.channels[it.name()] = it.channel().type == Imf::HALF    ? ExrPixelType::kHalf
                              : it.channel().type == Imf::UINT ? ExrPixelType::kUint
                                                               : ExrPixelType::kFloat;
  return out;
}

std::vector<uint8_t> encode_exr_impl(const char* name, const Image& img, const ExrWriteOptions& opt) {
  const PixelWindow data = exr_layout::data_window(img, opt);
  const Imf::Header header = exr_layout::header(img, opt, data);
  const exr_layout::Frame frame = exr_layout::frame(img, opt, data);
  MemoryOStream stream(name);
  if (opt.compression == ExrCompression::kNone) {
    if (write_uncompressed_exr(stream, header, frame.buffer)) return stream.take();
  }
  if (write_zip_exr(stream, header, frame.buffer, exr_layout::compression_threads())) return stream.take();
  {
    Imf::OutputFile out(stream, header, opt.compression == ExrCompression::kNone ? 0 : exr_layout::compression_threads());
    out.setFrameBuffer(frame.buffer);
    out.writePixels(img.height);
  }  // the destructor completes the file (its line offset table)
  return stream.take();
}

// sRGB OETF of a linear value, clamped to [0,1] (NaN -> 0), rounded to 8 bits.
uint8_t to_srgb8(float v) {
  if (!(v > 0.f)) return 0;
  if (v >= 1.f) return 255;
  const float e = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.f / 2.4f) - 0.055f;
  return uint8_t(std::lround(e * 255.f));
}

std::vector<uint8_t> srgb8_impl(const Image& img, float exposure) {
  check_rgb_shape(img);
  std::vector<uint8_t> pixels(img.rgb.size());
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = to_srgb8(img.rgb[i] * exposure);
  return pixels;
}

std::vector<uint8_t> encode_png_impl(const Image& img, float exposure) {
  check_rgb_shape(img);
  if (img.width == 0 || img.height == 0) throw std::runtime_error("a PNG cannot hold an empty image");
  const std::vector<uint8_t> pixels = srgb8_impl(img, exposure);

  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  image.width = png_uint_32(img.width);
  image.height = png_uint_32(img.height);
  image.format = PNG_FORMAT_RGB;  // 8-bit, non-linear: libpng tags the file sRGB
  png_alloc_size_t size = PNG_IMAGE_PNG_SIZE_MAX(image);
  std::vector<uint8_t> png(size);
  if (!png_image_write_to_memory(&image, png.data(), &size, 0, pixels.data(), 0, nullptr))
    throw std::runtime_error(std::string("libpng: ") + image.message);
  png.resize(size);
  return png;
}

}  // namespace

Image Image::make(int width, int height) {
  if (width < 0 || height < 0)
    throw ImageError("Image::make: negative size " + std::to_string(width) + "x" + std::to_string(height));
  Image img;
  img.width = width;
  img.height = height;
  assign_zeroed(img.rgb, 3 * size_t(width) * size_t(height));
  return img;
}

std::vector<uint8_t> exr_layout::encode(const char* name, const Image& img, const ExrWriteOptions& opt) {
  return encode_exr_impl(name, img, opt);
}

Image image_rows(const Image& img, int y0, int y1) {
  if (y0 < 0 || y1 < y0 || y1 > img.height)
    throw ImageError("image_rows: rows [" + std::to_string(y0) + ", " + std::to_string(y1) + ") are not rows of a " +
                     std::to_string(img.height) + "-row image");
  const size_t n = size_t(img.width) * size_t(img.height);
  const auto check = [&](const std::string& name, size_t size) {
    if (size != n)
      throw ImageError("image_rows: channel " + name + " has " + std::to_string(size) + " values, expected " +
                       std::to_string(n));
  };
  if (img.rgb.size() != 3 * n)
    throw ImageError("image_rows: " + std::to_string(img.rgb.size()) + " colour values, expected " +
                     std::to_string(3 * n));
  for (const auto& [name, values] : img.extra) check(name, values.size());
  for (const auto& [name, values] : img.uint_extra) check(name, values.size());
  const size_t first = size_t(y0) * size_t(img.width), end = size_t(y1) * size_t(img.width);
  Image rows = Image::make(img.width, y1 - y0);
  std::copy(img.rgb.begin() + std::ptrdiff_t(3 * first), img.rgb.begin() + std::ptrdiff_t(3 * end), rows.rgb.begin());
  for (const auto& [name, values] : img.extra)
    rows.extra[name].assign(values.begin() + std::ptrdiff_t(first), values.begin() + std::ptrdiff_t(end));
  for (const auto& [name, values] : img.uint_extra)
    rows.uint_extra[name].assign(values.begin() + std::ptrdiff_t(first), values.begin() + std::ptrdiff_t(end));
  return rows;
}

ExrImage read_exr(const std::filesystem::path& path, const ExrReadOptions& options) {
  return with_context("cannot read EXR " + quoted(path), [&] { return read_exr_impl(path, options); });
}

ExrHeader read_exr_header(const std::filesystem::path& path) {
  return with_context("cannot read EXR " + quoted(path), [&] { return read_exr_header_impl(path); });
}

ExrImage decode_exr(std::string_view bytes, const ExrReadOptions& options) {
  return with_context("cannot read EXR data", [&] { return decode_exr_impl(bytes, options); });
}

void write_exr(const std::filesystem::path& path, const Image& img, const ExrWriteOptions& opt) {
  with_context("cannot write EXR " + quoted(path),
               [&] { write_file_atomic(path, encode_exr_impl(path.c_str(), img, opt)); });
}

std::vector<uint8_t> encode_exr(const Image& img, const ExrWriteOptions& opt) {
  return with_context("cannot encode EXR", [&] { return encode_exr_impl("memory", img, opt); });
}

std::vector<uint8_t> srgb8_pixels(const Image& img, float exposure) {
  return with_context("cannot tone-map", [&] { return srgb8_impl(img, exposure); });
}

std::vector<uint8_t> encode_png_srgb(const Image& img, float exposure) {
  return with_context("cannot encode PNG", [&] { return encode_png_impl(img, exposure); });
}

void write_png_srgb(const std::filesystem::path& path, const Image& img, float exposure) {
  with_context("cannot write PNG " + quoted(path),
               [&] { write_file_atomic(path, encode_png_impl(img, exposure)); });
}

}  // namespace tessera
