// The pixel files of a store's jobs (server/tile_pixel_file.h), DIR/<job>.pixels, and which of them the next flush
// must make durable: a group commit flushes them before the database, so that no row naming a tile's bytes is
// durable before the bytes are.
#pragma once

#include "server/tile_pixel_file.h"

#include <cstddef>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// Every job's pixel file in one folder. Thread-safe; appends and cuts come from one thread at a time.
class PixelFiles {
 public:
  /// The files in `dir`, which is made if missing. With `durable`, its entry is flushed to the disk and sync_written()
  /// flushes what was written; without, nothing is flushed. Throws StorageError.
  PixelFiles(std::filesystem::path dir, bool durable);

  /// Appends a done tile's bytes to `job`'s file, made if missing (TilePixelFile::append); the file is flushed by the
  /// next sync_written(). Throws DiskFullError or StorageError, the file then as it was.
  PixelRef append(const std::string& job, std::string_view bytes);
  /// Cuts `job`'s file back to `size` bytes: the appends of a change the database did not store. Throws StorageError.
  void cut(const std::string& job, int64_t size);
  /// The bytes of a tile of `job` at `ref`, or nothing when the file does not hold them intact. Throws StorageError
  /// when the file cannot be read.
  std::optional<std::string> read(const std::string& job, const PixelRef& ref);
  /// Flushes every file appended to since the last call, and the folder when a file was made in it; throws
  /// StorageError. Returns the files of jobs purged before the call (remove_when_flushed), to be deleted once the
  /// database that no longer names them is flushed too.
  std::vector<std::filesystem::path> sync_written();
  /// Deletes `job`'s file after the next sync_written() and the database's flush (delete_files).
  void remove_when_flushed(const std::string& job);
  /// Deletes `job`'s file now.
  void remove(const std::string& job);
  /// Deletes files (as sync_written returned them); throws StorageError.
  static void delete_files(const std::vector<std::filesystem::path>& files);
  /// Deletes the files of jobs not in `jobs` (a crash came between a purge and the removal of its files); returns how
  /// many. Throws StorageError.
  size_t keep_only(const std::set<std::string>& jobs);
  /// `job`'s file.
  std::filesystem::path file_of(const std::string& job) const;

 private:
  std::shared_ptr<TilePixelFile> open_locked(const std::string& job, bool create);  // mu_ held
  void close_locked(const std::string& job);                                         // mu_ held

  const std::filesystem::path dir_;
  const bool durable_;
  std::mutex mu_;
  std::map<std::string, std::shared_ptr<TilePixelFile>> open_;     // job -> its file, as far as kept open
  std::map<std::string, std::shared_ptr<TilePixelFile>> written_;  // appended to since the last sync_written
  bool made_file_ = false;                  // a file was made since the last sync_written
  std::vector<std::filesystem::path> doomed_;  // files of purged jobs, deleted after the next flush
};

}  // namespace tessera::server
