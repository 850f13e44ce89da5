#include "core/image/exr_zip.h"

#include <libdeflate.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <memory>
#include <new>
#include <stdexcept>

namespace tessera {

int zip_lines_per_chunk(Imf::Compression c) {
  return c == Imf::ZIP_COMPRESSION ? 16 : c == Imf::ZIPS_COMPRESSION ? 1 : 0;
}

ZipChunkCompressor::ZipChunkCompressor(int level)
    : compressor_(libdeflate_alloc_compressor(level < 0 ? 6 : std::min(level, 12))) {
  if (!compressor_) throw std::bad_alloc();
}

ZipChunkCompressor::~ZipChunkCompressor() { libdeflate_free_compressor(compressor_); }

std::vector<char> ZipChunkCompressor::compress(const char* raw, size_t size) {
  // OpenEXR's ZIP: the even-position bytes, then the odd ones; each byte then replaced by its difference from the one
  // before plus 128 (mod 256), the first kept.
  predicted_.resize(size);
  const auto* in = reinterpret_cast<const uint8_t*>(raw);
  uint8_t* even = predicted_.data();
  uint8_t* odd = predicted_.data() + (size + 1) / 2;
  for (size_t i = 0; i + 1 < size; i += 2) {
    *even++ = in[i];
    *odd++ = in[i + 1];
  }
  if (size & 1) *even = in[size - 1];
  for (size_t i = size; i-- > 1;) predicted_[i] = uint8_t(predicted_[i] - predicted_[i - 1] + 128);
  std::vector<char> out(libdeflate_zlib_compress_bound(compressor_, size));
  const size_t n = libdeflate_zlib_compress(compressor_, predicted_.data(), size, out.data(), out.size());
  if (n == 0 || n >= size) return std::vector<char>(raw, raw + size);
  out.resize(n);
  return out;
}

bool write_zip_exr(Imf::OStream& os, const Imf::Header& header, const Imf::FrameBuffer& frame, int threads) {
  const int per_chunk = zip_lines_per_chunk(header.compression());
  if (per_chunk == 0) return false;
  const std::optional<exr_scanline::Lines> lines = exr_scanline::Lines::of(header, frame);
  if (!lines) return false;
  header.sanityCheck();  // before any work, as OutputFile checks it first
  const Imath::Box2i dw = header.dataWindow();
  const int64_t y0 = dw.min.y, height = int64_t(dw.max.y) - dw.min.y + 1;
  std::vector<std::vector<char>> chunks(size_t((height + per_chunk - 1) / per_chunk));
  struct Scratch {
    ZipChunkCompressor compressor;
    std::vector<char> raw;
  };
  const int level = header.zipCompressionLevel();
  tbb::enumerable_thread_specific<Scratch> scratch([&] { return Scratch{ZipChunkCompressor(level), {}}; });
  const auto compress = [&](size_t i) {
    Scratch& s = scratch.local();
    const int64_t first = y0 + int64_t(i) * per_chunk, last = std::min(y0 + height, first + per_chunk);
    s.raw.resize(size_t(last - first) * lines->line_bytes());
    for (int64_t y = first; y < last; ++y) lines->pack(y, s.raw.data() + size_t(y - first) * lines->line_bytes());
    chunks[i] = s.compressor.compress(s.raw.data(), s.raw.size());
  };
  if (threads > 1 && chunks.size() > 1) {
    tbb::parallel_for(size_t(0), chunks.size(), compress);
  } else {
    for (size_t i = 0; i < chunks.size(); ++i) compress(i);
  }
  exr_scanline::write_start(os, header);
  exr_scanline::write_chunks(os, y0, per_chunk, chunks);
  return true;
}

ZipChunkStream::ZipChunkStream(const Imf::Header& header)
    : y0_(header.dataWindow().min.y),
      height_(int64_t(header.dataWindow().max.y) - header.dataWindow().min.y + 1),
      compression_(header.compression()),
      level_(header.zipCompressionLevel()),
      lines_per_chunk_(zip_lines_per_chunk(header.compression())),
      compressor_(header.zipCompressionLevel()) {
  if (lines_per_chunk_ == 0) throw std::invalid_argument("a ZIP chunk stream needs ZIP or ZIPS compression");
}

void ZipChunkStream::add(const exr_scanline::Lines& lines, int64_t y0, int64_t y1) {
  if (y0 != y0_ + added_ || y1 < y0 || y1 > y0_ + height_)
    throw std::invalid_argument("lines added out of order or past the data window");
  if (added_ == 0) line_bytes_ = lines.line_bytes();
  if (lines.line_bytes() != line_bytes_) throw std::invalid_argument("lines of another size than the first ones");
  for (int64_t y = y0; y < y1; ++y) {
    const size_t at = pending_.size();
    pending_.resize(at + line_bytes_);
    lines.pack(y, pending_.data() + at);
    ++added_;
    if (added_ % lines_per_chunk_ == 0 || added_ == height_) {
      chunks_.push_back(compressor_.compress(pending_.data(), pending_.size()));
      pending_.clear();
    }
  }
}

bool ZipChunkStream::fits(const Imf::Header& header) const {
  const Imath::Box2i dw = header.dataWindow();
  return added_ == height_ && dw.min.y == y0_ && int64_t(dw.max.y) - dw.min.y + 1 == height_ &&
         header.compression() == compression_ && header.zipCompressionLevel() == level_;
}

void ZipChunkStream::write(Imf::OStream& os, const Imf::Header& header) const {
  exr_scanline::write_start(os, header);
  exr_scanline::write_chunks(os, y0_, lines_per_chunk_, chunks_);
}

}  // namespace tessera
