#include "core/image/exr_multipart.h"

#include "core/image/exr_io.h"
#include "core/image/exr_layout.h"
#include "core/util/file_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfVersion.h>

#include <fstream>
#include <set>

namespace tessera {

namespace {

Imath::Box2i box_of(const PixelWindow& w) { return Imath::Box2i({w.x0, w.y0}, {w.x1 - 1, w.y1 - 1}); }

std::vector<uint8_t> encode_parts(const Image& img, const ExrWriteOptions& opt, const std::vector<ExrPart>& parts) {
  // The first part: the image without the channels later parts hold.
  std::set<std::string> elsewhere;
  for (const ExrPart& p : parts)
    for (const std::string& c : p.channels) {
      if (!img.extra.count(c)) throw std::runtime_error("no channel \"" + c + "\" for part \"" + p.name + "\"");
      if (!elsewhere.insert(c).second) throw std::runtime_error("channel \"" + c + "\" is in two parts");
    }
  Image first;
  first.width = img.width;
  first.height = img.height;
  first.rgb = img.rgb;
  first.uint_extra = img.uint_extra;
  for (const auto& [name, values] : img.extra)
    if (!elsewhere.count(name)) first.extra.emplace(name, values);
  const PixelWindow data = exr_layout::data_window(first, opt);
  std::vector<Imf::Header> headers;
  headers.push_back(exr_layout::header(first, opt, data));
  headers.back().setName("rgba");
  headers.back().setType(Imf::SCANLINEIMAGE);
  for (const ExrPart& p : parts) {
    Imf::Header h = headers.front();
    h.channels() = Imf::ChannelList();
    for (const std::string& c : p.channels) h.channels().insert(c, Imf::Channel(Imf::FLOAT));
    h.setName(p.name);
    headers.push_back(std::move(h));
  }
  exr_io::MemoryOStream stream("memory");
  {
    Imf::MultiPartOutputFile out(stream, headers.data(), int(headers.size()), false,
                                 opt.compression == ExrCompression::kNone ? 0 : exr_layout::compression_threads());
    {
      const exr_layout::Frame frame = exr_layout::frame(first, opt, data);
      Imf::OutputPart part(out, 0);
      part.setFrameBuffer(frame.buffer);
      part.writePixels(img.height);
    }
    const Imath::Box2i box = box_of(data);
    for (size_t i = 0; i < parts.size(); ++i) {
      Imf::FrameBuffer fb;
      for (const std::string& c : parts[i].channels)
        fb.insert(c, Imf::Slice::Make(Imf::FLOAT, img.extra.at(c).data(), box));
      Imf::OutputPart part(out, int(i + 1));
      part.setFrameBuffer(fb);
      part.writePixels(img.height);
    }
  }  // the destructor completes the file (its offset tables)
  return stream.take();
}

void read_further_parts(const std::filesystem::path& path, ExrImage& out) {
  Imf::MultiPartInputFile in(path.c_str());
  const Imath::Box2i first = box_of(out.data_window);
  Image& img = out.pixels;
  const size_t npix = size_t(img.width) * size_t(img.height);
  for (int p = 1; p < in.parts(); ++p) {
    const Imf::Header& h = in.header(p);
    if (h.dataWindow() != first)
      throw std::runtime_error("part " + std::to_string(p) + " has another data window than the first part");
    if (h.hasType() && h.type() != Imf::SCANLINEIMAGE && h.type() != Imf::TILEDIMAGE)
      throw std::runtime_error("part " + std::to_string(p) + " is not a flat image");
    Imf::FrameBuffer fb;
    for (auto c = h.channels().begin(); c != h.channels().end(); ++c) {
      if (c.channel().xSampling != 1 || c.channel().ySampling != 1) continue;
      const std::string name = c.name();
      if (img.extra.count(name) || img.uint_extra.count(name) || name == "R" || name == "G" || name == "B")
        throw std::runtime_error("channel \"" + name + "\" appears in two parts");
      if (c.channel().type == Imf::UINT) {
        std::vector<uint32_t>& v = img.uint_extra[name];
        v.assign(npix, 0u);
        fb.insert(name, Imf::Slice::Make(Imf::UINT, v.data(), first));
      } else {
        std::vector<float>& v = img.extra[name];
        v.assign(npix, 0.f);
        fb.insert(name, Imf::Slice::Make(Imf::FLOAT, v.data(), first));
      }
    }
    Imf::InputPart part(in, p);
    part.setFrameBuffer(fb);
    part.readPixels(first.min.y, first.max.y);
  }
}

bool is_multipart(const std::filesystem::path& path) {
  std::ifstream f(path, std::ios::binary);
  char start[8] = {};
  f.read(start, 8);
  if (f.gcount() < 8 || !Imf::isImfMagic(start)) return false;
  int version = 0;
  for (int i = 0; i < 4; ++i) version |= int(static_cast<unsigned char>(start[4 + i])) << (8 * i);
  return Imf::isMultiPart(version);
}

}  // namespace

std::vector<uint8_t> encode_exr_multipart(const Image& img, const ExrWriteOptions& opt, const std::vector<ExrPart>& parts) {
  try {
    return encode_parts(img, opt, parts);
  } catch (const ImageError&) {
    throw;
  } catch (const std::exception& e) {
    throw ImageError(std::string("cannot encode multi-part EXR: ") + e.what());
  }
}

void write_exr_multipart(const std::filesystem::path& path, const Image& img, const ExrWriteOptions& opt,
                         const std::vector<ExrPart>& parts) {
  try {
    write_file_atomic(path, encode_parts(img, opt, parts));
  } catch (const std::exception& e) {
    throw ImageError("cannot write EXR " + exr_io::quoted(path) + ": " + e.what());
  }
}

ExrImage read_exr_all_parts(const std::filesystem::path& path, const ExrReadOptions& options) {
  ExrImage out = read_exr(path, options);
  if (options.colour_only || !is_multipart(path)) return out;
  try {
    read_further_parts(path, out);
  } catch (const std::exception& e) {
    throw ImageError("cannot read EXR " + exr_io::quoted(path) + ": " + e.what());
  }
  return out;
}

}  // namespace tessera
