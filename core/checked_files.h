// The image files earlier scene checks decoded clean, for files that do not change, so that checking another scene
// that uses them need not decode them again.
#pragma once

#include <cstddef>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>

namespace tessera {

/// Image files that decoded as textures with only finite pixels, each with its SHA-256 (as sha256_file() gives it),
/// for files that are never rewritten in place (a content-addressed store's): an entry is found while the path names
/// the same file (device and inode) with the same size as when it was recorded. The modification time is not
/// compared: such a store touches its files to mark them used. Thread-safe; holds at most `capacity` files,
/// forgetting the earliest recorded first.
class CheckedFiles {
 public:
  /// An empty record that keeps at most `capacity` files (at least one).
  explicit CheckedFiles(size_t capacity = 4096);

  /// The SHA-256 recorded for `file`, if it was recorded and is unchanged since.
  std::optional<std::string> find(const std::filesystem::path& file) const;

  /// Records `file` as it is now, with its SHA-256 (nothing is recorded when it cannot be examined).
  void remember(const std::filesystem::path& file, std::string sha256);

  /// Number of files recorded.
  size_t size() const;

 private:
  struct Entry {
    std::string identity;  // device, inode and size when recorded
    std::string sha256;
  };
  size_t capacity_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, Entry> entries_;  // by path
  std::deque<std::string> order_;                    // paths, earliest recorded first
};

}  // namespace tessera
