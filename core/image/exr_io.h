// OpenEXR's I/O streams over memory (in and out) and over a file that replaces another atomically. Internal to core/
// (it includes OpenEXR's headers, which core/ links privately).
#pragma once

#include <OpenEXR/ImfIO.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::exr_io {

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

}  // namespace tessera::exr_io
