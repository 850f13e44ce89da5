// What earlier scene checks learnt about asset files that do not change, so that checking another scene that uses
// them need not read them again.
#pragma once

#include <cstddef>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>

namespace tessera {

/// What a scene check learnt about one asset file.
struct CheckedFile {
  std::string sha256;     ///< The file's SHA-256, as sha256_file() gives it.
  bool image_ok = false;  ///< The file decoded as an image texture with only finite pixels.
};

/// Facts about asset files, for files that are never rewritten in place (a content-addressed store's): an entry is
/// found while the path names the same file (device and inode) with the same size as when it was recorded. The
/// modification time is not compared: such a store touches its files to mark them used. Thread-safe; holds at most
/// `capacity` files, forgetting the earliest recorded first.
class CheckedFiles {
 public:
  /// An empty record that keeps at most `capacity` files (at least one).
  explicit CheckedFiles(size_t capacity = 4096);

  /// What was recorded for `file`, if the file is unchanged since.
  std::optional<CheckedFile> find(const std::filesystem::path& file) const;

  /// Records `facts` for `file` as it is now (nothing is recorded when it cannot be examined).
  void remember(const std::filesystem::path& file, CheckedFile facts);

  /// Number of files recorded.
  size_t size() const;

 private:
  struct Entry {
    std::string identity;  // device, inode and size when recorded
    CheckedFile facts;
  };
  size_t capacity_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, Entry> entries_;  // by path
  std::deque<std::string> order_;                    // paths, earliest recorded first
};

}  // namespace tessera
