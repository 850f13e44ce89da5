// An OpenEXR file written in bands of rows while its image is still being made (e.g. during a render).
#pragma once

#include "core/image/image.h"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

namespace tessera {

/// Writes an EXR band by band as rows of its image become final (e.g. from RenderOptions::rows_final), so that
/// little is left to compress once the image is done; the file is byte for byte the one write_exr writes of the
/// finished image. Each band is compressed on the calling thread into memory, in the line blocks of a one-shot write
/// (a block once all its rows are there): ZIP and ZIPS blocks by libdeflate (exr_zip.h), other compressions by
/// OpenEXR; finish() puts the compressed blocks under the final header, whose metadata may be known only then.
class ExrStream {
 public:
  /// A stream for a file laid out as `layout` says: its data window (which must not be empty), display window,
  /// compression, half colours and write_extra. Its metadata is not used: finish() takes the final options.
  explicit ExrStream(const ExrWriteOptions& layout);
  ~ExrStream();
  ExrStream(const ExrStream&) = delete;
  ExrStream& operator=(const ExrStream&) = delete;

  /// Rows of the data window written so far: the next band starts there.
  int rows_written() const;

  /// Compresses the next band: `band` holds rows [rows_written(), rows_written() + band.height) of the data window,
  /// with every channel the file will have (the first band sets them; later bands must have the same). Not
  /// thread-safe: one call at a time. Throws ImageError; the stream then stops, and finish() encodes afresh.
  void write_rows(const Image& band);

  /// encode_exr(img, opt)'s bytes. When the stream holds every row in the layout of (img, opt) (same data window,
  /// compression and channels: names, and types as opt.half and opt.write_extra make them), its compressed blocks
  /// are used as they are, so img's pixels must be those that were written; otherwise img is encoded afresh. The
  /// stream is spent afterwards (a second call encodes afresh). Throws ImageError as encode_exr does.
  std::vector<uint8_t> finish(const Image& img, const ExrWriteOptions& opt);

  /// write_exr(path, img, opt), with the bytes of finish(img, opt): atomic, and on failure path is untouched.
  /// Throws ImageError naming the file.
  void write(const std::filesystem::path& path, const Image& img, const ExrWriteOptions& opt);

  /// True when finish() would reuse the compressed blocks for an image and options of the stream's layout (every
  /// row written, no failure).
  bool complete() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tessera
