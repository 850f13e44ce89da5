#include "core/checked_files.h"

#include <sys/stat.h>

#include <algorithm>

namespace fs = std::filesystem;

namespace tessera {

namespace {

// Device, inode and size of a regular file, or nothing when it cannot be examined.
std::optional<std::string> identity_of(const fs::path& file) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino) + ":" + std::to_string(st.st_size);
}

}  // namespace

CheckedFiles::CheckedFiles(size_t capacity) : capacity_(std::max<size_t>(1, capacity)) {}

std::optional<std::string> CheckedFiles::find(const fs::path& file) const {
  const std::optional<std::string> id = identity_of(file);
  if (!id) return std::nullopt;
  std::lock_guard lock(mu_);
  const auto it = entries_.find(file.string());
  if (it == entries_.end() || it->second.identity != *id) return std::nullopt;
  return it->second.sha256;
}

void CheckedFiles::remember(const fs::path& file, std::string sha256) {
  std::optional<std::string> id = identity_of(file);
  if (!id) return;
  std::lock_guard lock(mu_);
  const std::string key = file.string();
  if (const auto it = entries_.find(key); it != entries_.end()) {
    it->second = {std::move(*id), std::move(sha256)};
    return;
  }
  if (entries_.size() >= capacity_) {
    entries_.erase(order_.front());
    order_.pop_front();
  }
  entries_.emplace(key, Entry{std::move(*id), std::move(sha256)});
  order_.push_back(key);
}

size_t CheckedFiles::size() const {
  std::lock_guard lock(mu_);
  return entries_.size();
}

}  // namespace tessera
