// One job's done tiles' pixel bytes, appended one tile after another to a file of their own beside the database; the
// tile's row keeps only where its bytes are (a PixelRef), so the bytes are written once and never pass through the
// database's write-ahead log.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace tessera::server {

/// Where a tile's bytes are in its job's pixel file, and their checksum (pixel_checksum).
struct PixelRef {
  int64_t offset = 0;     ///< First byte.
  int64_t length = 0;     ///< Byte count.
  uint64_t checksum = 0;  ///< pixel_checksum of the bytes.
};

/// A 64-bit checksum of `bytes` that tells damaged or missing bytes (zeros, a cut, garbage) from the ones written;
/// not a cryptographic hash.
uint64_t pixel_checksum(std::string_view bytes);

/// An append-only file of tile bytes. Appends and cuts come from one thread at a time; read() and sync() may run on
/// other threads meanwhile.
class TilePixelFile {
 public:
  /// Opens `path`, creating it when `create` is true; without `create`, a missing file is an empty one that refuses
  /// appends. Throws StorageError.
  TilePixelFile(std::filesystem::path path, bool create);
  ~TilePixelFile();
  TilePixelFile(const TilePixelFile&) = delete;
  TilePixelFile& operator=(const TilePixelFile&) = delete;

  /// Writes `bytes` at the end of the file with one pwrite, the space reserved first (fallocate) so that the flush
  /// cannot fail for want of it. Throws DiskFullError when the disk has no room, StorageError on other failures; the
  /// file is then as it was.
  PixelRef append(std::string_view bytes);
  /// The bytes `ref` names, or nothing when the file does not hold them whole or they fail their checksum. Throws
  /// StorageError when the file cannot be read.
  std::optional<std::string> read(const PixelRef& ref) const;
  /// Makes every append so far durable (fdatasync); throws StorageError.
  void sync();
  /// Cuts the file back to `size` bytes (the appends of a change that was not stored); throws StorageError.
  void cut(int64_t size);
  /// True when the file was missing and not created.
  bool missing() const { return fd_ < 0; }
  /// Bytes written so far.
  int64_t size() const { return end_; }
  /// The file.
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;  // -1: a missing file opened without `create`
  int64_t end_ = 0;       // where the next append goes
  int64_t reserved_ = 0;  // bytes allocated on the disk (fallocate), >= end_ where the file system supports it
};

}  // namespace tessera::server
