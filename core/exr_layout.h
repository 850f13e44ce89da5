// How an Image is laid out as an OpenEXR file: the pieces write_exr and ExrStream share. Internal to core/ (it
// includes OpenEXR's headers, which core/ links privately); the public interface is core/image.h and core/exr_stream.h.
#pragma once

#include "core/image.h"

#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <Imath/half.h>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::exr_layout {

/// An OpenEXR output stream into memory.
class MemoryOStream final : public Imf::OStream {
 public:
  /// An empty stream; `name` appears in OpenEXR's error messages.
  explicit MemoryOStream(const char* name) : Imf::OStream(name) {}
  void write(const char c[], int n) override;
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = size_t(pos); }
  /// Makes room for n bytes in all, so that writing up to that many does not move them again.
  void reserve(size_t n) { bytes_.reserve(n); }
  /// Everything written.
  const std::vector<uint8_t>& bytes() const { return bytes_; }
  /// Everything written, moved out.
  std::vector<uint8_t> take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
  size_t pos_ = 0;
};

/// An OpenEXR input stream over bytes in memory, which must outlive it.
class MemoryIStream final : public Imf::IStream {
 public:
  /// A stream at the first of `bytes`; `name` appears in OpenEXR's error messages.
  MemoryIStream(std::string_view bytes, const char* name) : Imf::IStream(name), bytes_(bytes) {}
  bool read(char c[], int n) override;
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = size_t(pos); }
  void clear() override {}

 private:
  std::string_view bytes_;
  size_t pos_ = 0;
};

/// The data window of a file of img written with opt (opt.data_window, or img's size at the origin). Throws
/// std::runtime_error for a malformed or empty img, or a data window of another width (and, unless `band`, height).
PixelWindow data_window(const Image& img, const ExrWriteOptions& opt, bool band = false);

/// The header write_exr writes for an image with img's channels laid out as opt says over `data`: windows,
/// compression, opt.metadata, and the channels R,G,B (float or half) plus, with opt.write_extra, img's extra
/// channels (float) and uint_extra channels (UINT). Throws std::runtime_error for metadata that names a standard
/// attribute and for colliding channel names.
Imf::Header header(const Image& img, const ExrWriteOptions& opt, const PixelWindow& data);

/// A frame buffer over img's channels, img holding the pixels of `rows` (a window of whole rows of the data window,
/// in EXR pixel space), with the half copy of its colours that half output needs.
struct Frame {
  Imf::FrameBuffer buffer;     ///< The slices, addressed by absolute pixel coordinates.
  std::vector<half> rgb_half;  ///< img's colours as half (opt.half only); the colour slices point into it.
};

/// Throws std::runtime_error when an extra channel that opt writes has another size than img's.
void check_extra_sizes(const Image& img, const ExrWriteOptions& opt);

/// The frame of img's channels as header(img, opt, ...) lists them; throws as check_extra_sizes does.
Frame frame(const Image& img, const ExrWriteOptions& opt, const PixelWindow& rows);

/// encode_exr's bytes, throwing std::runtime_error (or OpenEXR's errors) without context; `name` appears in
/// OpenEXR's messages.
std::vector<uint8_t> encode(const char* name, const Image& img, const ExrWriteOptions& opt);

/// Threads for compressing an EXR: as many as the render may use (--threads), OpenEXR's pool resized to that.
int compression_threads();

/// A file written as an OpenEXR output stream (buffered) to a temp file beside path, which commit() syncs and renames over
/// path, so path is never seen half-written. Dropped without a commit, it removes the temporary and path stays as it
/// was. Errors throw std::runtime_error naming the file; one that OpenEXR swallows (it writes the line offset table
/// from a destructor) is thrown again by commit().
class AtomicFile final : public Imf::OStream {
 public:
  /// Creates the temp file (temp_path_beside).
  explicit AtomicFile(const std::filesystem::path& path);
  ~AtomicFile() override;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  void write(const char c[], int n) override;
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = pos; }
  /// Writes out what is buffered, syncs the file, renames it over path and syncs the folder.
  void commit();
  /// True once a write has failed (commit() then throws).
  bool failed() const { return !failure_.empty(); }

 private:
  void flush();                                            // writes buffer_ at buffer_pos_
  void write_at(const char* data, size_t n, uint64_t at);  // all n bytes at offset `at`, or throws
  [[noreturn]] void fail(const std::string& what, int err);

  std::filesystem::path path_, tmp_;
  int fd_ = -1;
  std::vector<char> buffer_;  // bytes for the file from buffer_pos_ on
  uint64_t buffer_pos_ = 0;
  uint64_t pos_ = 0;          // where the next write goes
  std::string failure_;       // the first error, thrown again by commit()
  bool committed_ = false;
};

/// `p` in double quotes, for messages.
std::string quoted(const std::filesystem::path& p);

}  // namespace tessera::exr_layout
