// The image files earlier scene loads decoded clean, for files that do not change: checking another scene that uses
// them need not decode them again, and a load that builds may take the decoded pixels themselves where they were kept,
// with the environment sampling table built from them.
#pragma once

#include "core/image/image.h"
#include "core/sampling/sampling.h"

#include <cstddef>
#include <filesystem>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>

namespace tessera {

/// Image files that decoded as textures with only finite pixels, each with its SHA-256 (as sha256_file() gives it) and,
/// within a byte budget, its decoded pixels; for files that are never rewritten in place (a content-addressed
/// store's): an entry is found while the path names the same file (device and inode) with the same size as when it
/// was recorded. The modification time is not compared: such a store touches its files to mark them used.
/// Thread-safe; holds at most `capacity` files, forgetting the least recently used first, and keeps pixels (with what
/// was derived from them) of the most recently used files up to `image_bytes` bytes in all.
class CheckedFiles {
 public:
  /// What was recorded for a file: its SHA-256, its pixels (null when they were not kept) and the environment sampling
  /// table built from those pixels (null when none was recorded).
  struct Record {
    std::string sha256;
    std::shared_ptr<const Image> image;
    std::shared_ptr<const Distribution2D> environment;
  };

  /// An empty record that keeps at most `capacity` files (at least one) and pixels of up to `image_bytes` bytes.
  explicit CheckedFiles(size_t capacity = 4096, size_t image_bytes = 0);

  /// What was recorded for `file`, if it was recorded and is unchanged since (now its most recently used).
  std::optional<Record> find(const std::filesystem::path& file);

  /// Records `file` as it is now, with its SHA-256 and, if given and within the budget, its pixels (nothing is
  /// recorded when the file cannot be examined).
  void remember(const std::filesystem::path& file, std::string sha256, std::shared_ptr<const Image> image = nullptr);

  /// Adds the environment sampling table built from `pixels` to the record of `file`, when the record still holds those
  /// very pixels (the same object) for the unchanged file and both fit in the budget; they are then kept and dropped
  /// together.
  void remember_environment(const std::filesystem::path& file, const Image* pixels,
                            std::shared_ptr<const Distribution2D> table);

  /// Number of files recorded.
  size_t size() const;

  /// Bytes of pixels and of the tables built from them kept.
  size_t image_bytes() const;

 private:
  struct Entry {
    std::string path;
    std::string identity;  // device, inode and size when recorded
    Record record;
    size_t bytes = 0;      // of record.image's pixels and record.environment's table
  };
  void trim_locked();

  size_t capacity_, image_budget_;
  mutable std::mutex mu_;
  std::list<Entry> order_;  // most recently used first
  std::unordered_map<std::string, std::list<Entry>::iterator> entries_;  // by path
  size_t image_bytes_ = 0;
};

}  // namespace tessera
