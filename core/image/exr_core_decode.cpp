#include "core/image/exr_core_decode.h"

#include <openexr.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <limits>
#include <vector>

namespace tessera::exr_core {
namespace {

// Blocks per task when a large image is decoded on several threads, and the fewest pixels worth splitting.
constexpr size_t kBlocksPerTask = 8;
constexpr int64_t kParallelPixels = 512 * 512;

int64_t read_bytes(exr_const_context_t, void* user, void* buffer, uint64_t size, uint64_t offset,
                   exr_stream_error_func_ptr_t) {
  const auto* bytes = static_cast<const std::string_view*>(user);
  if (offset >= bytes->size()) return 0;
  const uint64_t n = std::min<uint64_t>(size, bytes->size() - offset);
  std::memcpy(buffer, bytes->data() + offset, n);
  return int64_t(n);
}

int64_t byte_count(exr_const_context_t, void* user) { return int64_t(static_cast<const std::string_view*>(user)->size()); }

// OpenEXRCore would print its errors to stderr; a false return says enough (the C++ library then names the fault).
void quiet(exr_const_context_t, exr_result_t, const char*) {}

// Decodes `chunks` (read and checked by ScanlineDecoder::open) into the targets with a pipeline of its own; false on
// any error.
bool decode_blocks(exr_const_context_t ctx, const PixelWindow& window, std::span<const exr_chunk_info_t> chunks,
                   std::span<const ChannelTarget> targets) {
  exr_decode_pipeline_t dec{};  // EXR_DECODE_PIPELINE_INITIALIZER, which clang warns leaves fields to zero
  bool ok = true, initialised = false;
  for (const exr_chunk_info_t& chunk : chunks) {
    const exr_result_t set_up = initialised ? exr_decoding_update(ctx, 0, &chunk, &dec)
                                            : exr_decoding_initialize(ctx, 0, &chunk, &dec);
    if (set_up != EXR_ERR_SUCCESS) {
      ok = false;
      break;
    }
    const bool first_block = !initialised;
    initialised = true;
    size_t matched = 0;
    for (int16_t c = 0; c < dec.channel_count; ++c) {
      exr_coding_channel_info_t& ch = dec.channels[c];
      ch.decode_to_ptr = nullptr;  // channels without a target are skipped
      for (const ChannelTarget& t : targets) {
        if (t.name != ch.channel_name) continue;
        const bool is_uint = ch.data_type == EXR_PIXEL_UINT;
        const bool is_float = ch.data_type == EXR_PIXEL_HALF || ch.data_type == EXR_PIXEL_FLOAT;
        if (ch.x_samples != 1 || ch.y_samples != 1 || ch.width != window.width() || ch.height != chunk.height ||
            !(t.uint ? is_uint : is_float)) {
          ok = false;
          break;
        }
        ch.user_bytes_per_element = 4;
        ch.user_data_type = uint16_t(t.uint ? EXR_PIXEL_UINT : EXR_PIXEL_FLOAT);
        ch.user_pixel_stride = int32_t(t.pixel_stride);
        ch.user_line_stride = int32_t(t.line_stride);
        ch.decode_to_ptr = reinterpret_cast<uint8_t*>(t.first + size_t(chunk.start_y - window.y0) * t.line_stride);
        ++matched;
        break;
      }
    }
    if (!ok || matched != targets.size()) {
      ok = false;
      break;
    }
    // The unpacking routine depends on the targets' layout, which is the same for every block.
    if (first_block && exr_decoding_choose_default_routines(ctx, 0, &dec) != EXR_ERR_SUCCESS) ok = false;
    if (ok && exr_decoding_run(ctx, 0, &dec) != EXR_ERR_SUCCESS) ok = false;
  }
  if (initialised) exr_decoding_destroy(ctx, &dec);
  return ok;
}

}  // namespace

struct ScanlineDecoder::Impl {
  std::string_view bytes;  // read_bytes reads from here (the context holds its address)
  PixelWindow window;
  exr_context_t ctx = nullptr;
  std::vector<exr_chunk_info_t> chunks;  // every block of the data window, top to bottom
  ~Impl() {
    if (ctx) exr_finish(&ctx);
  }
};

ScanlineDecoder::ScanlineDecoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ScanlineDecoder::~ScanlineDecoder() = default;

std::unique_ptr<ScanlineDecoder> ScanlineDecoder::open(std::string_view bytes, const PixelWindow& window) {
  if (window.empty()) return nullptr;
  auto impl = std::make_unique<Impl>();
  impl->bytes = bytes;
  impl->window = window;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = quiet;
  init.user_data = &impl->bytes;
  init.read_fn = read_bytes;
  init.size_fn = byte_count;
  init.max_image_width = window.width();
  init.max_image_height = window.height();
  if (exr_start_read(&impl->ctx, "(memory)", &init) != EXR_ERR_SUCCESS) return nullptr;
  int parts = 0;
  exr_storage_t storage = EXR_STORAGE_LAST_TYPE;
  exr_compression_t compression = EXR_COMPRESSION_LAST_TYPE;
  exr_attr_box2i_t dw{};
  int32_t lines = 0, blocks = 0;
  const exr_context_t ctx = impl->ctx;
  if (exr_get_count(ctx, &parts) != EXR_ERR_SUCCESS || parts != 1 ||
      exr_get_storage(ctx, 0, &storage) != EXR_ERR_SUCCESS || storage != EXR_STORAGE_SCANLINE ||
      exr_get_compression(ctx, 0, &compression) != EXR_ERR_SUCCESS ||
      !(compression == EXR_COMPRESSION_NONE || compression == EXR_COMPRESSION_ZIPS ||
        compression == EXR_COMPRESSION_ZIP) ||
      exr_get_data_window(ctx, 0, &dw) != EXR_ERR_SUCCESS ||
      !(dw.min.x == window.x0 && dw.min.y == window.y0 && int64_t(dw.max.x) + 1 == window.x1 &&
        int64_t(dw.max.y) + 1 == window.y1) ||
      exr_get_scanlines_per_chunk(ctx, 0, &lines) != EXR_ERR_SUCCESS || lines <= 0 ||
      exr_get_chunk_count(ctx, 0, &blocks) != EXR_ERR_SUCCESS ||
      int64_t(blocks) != (int64_t(window.height()) + lines - 1) / lines)
    return nullptr;
  // Every block listed and inside the file (OpenEXRCore checks each offset and size against the file's size), its
  // rows the data window's.
  impl->chunks.resize(size_t(blocks));
  for (int block = 0; block < blocks; ++block) {
    exr_chunk_info_t& chunk = impl->chunks[size_t(block)];
    const int y = window.y0 + block * lines;
    if (exr_read_scanline_chunk_info(ctx, 0, y, &chunk) != EXR_ERR_SUCCESS || chunk.start_y != y ||
        chunk.height <= 0 || int64_t(chunk.start_y) + chunk.height > window.y1)
      return nullptr;
  }
  return std::unique_ptr<ScanlineDecoder>(new ScanlineDecoder(std::move(impl)));
}

bool ScanlineDecoder::decode(std::span<const ChannelTarget> targets) {
  if (targets.empty()) return false;
  for (const ChannelTarget& t : targets)
    if (!t.first || t.pixel_stride > size_t(std::numeric_limits<int32_t>::max()) ||
        t.line_stride > size_t(std::numeric_limits<int32_t>::max()))
      return false;
  const Impl& f = *impl_;
  const std::span<const exr_chunk_info_t> chunks(f.chunks);
  const int64_t pixels = int64_t(f.window.width()) * f.window.height();
  if (pixels < kParallelPixels || chunks.size() < 2 * kBlocksPerTask)
    return decode_blocks(f.ctx, f.window, chunks, targets);
  std::atomic<bool> ok{true};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks.size(), kBlocksPerTask), [&](const tbb::blocked_range<size_t>& r) {
    if (ok.load(std::memory_order_relaxed) &&
        !decode_blocks(f.ctx, f.window, chunks.subspan(r.begin(), r.size()), targets))
      ok.store(false, std::memory_order_relaxed);
  });
  return ok.load();
}

bool decode_scanlines(std::string_view bytes, const PixelWindow& window, std::span<const ChannelTarget> targets) {
  const std::unique_ptr<ScanlineDecoder> d = ScanlineDecoder::open(bytes, window);
  return d && d->decode(targets);
}

}  // namespace tessera::exr_core
