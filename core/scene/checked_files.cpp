#include "core/scene/checked_files.h"

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

size_t bytes_of(const Image& img) {
  size_t n = img.rgb.size() * sizeof(float);
  for (const auto& [name, values] : img.extra) n += values.size() * sizeof(float);
  for (const auto& [name, values] : img.uint_extra) n += values.size() * sizeof(uint32_t);
  return n;
}

}  // namespace

CheckedFiles::CheckedFiles(size_t capacity, size_t image_bytes)
    : capacity_(std::max<size_t>(1, capacity)), image_budget_(image_bytes) {}

std::optional<CheckedFiles::Record> CheckedFiles::find(const fs::path& file) {
  const std::optional<std::string> id = identity_of(file);
  if (!id) return std::nullopt;
  std::lock_guard lock(mu_);
  const auto it = entries_.find(file.string());
  if (it == entries_.end() || it->second->identity != *id) return std::nullopt;
  order_.splice(order_.begin(), order_, it->second);
  return it->second->record;
}

void CheckedFiles::remember(const fs::path& file, std::string sha256, std::shared_ptr<const Image> image) {
  std::optional<std::string> id = identity_of(file);
  if (!id) return;
  const size_t bytes = image ? bytes_of(*image) : 0;
  if (bytes > image_budget_) image.reset();  // never kept: it would push out everything else and still not fit
  std::lock_guard lock(mu_);
  const std::string key = file.string();
  if (const auto it = entries_.find(key); it != entries_.end()) {
    image_bytes_ -= it->second->bytes;
    order_.erase(it->second);
    entries_.erase(it);
  }
  order_.push_front(Entry{key, std::move(*id), Record{std::move(sha256), std::move(image), nullptr}, 0});
  order_.front().bytes = order_.front().record.image ? bytes : 0;
  image_bytes_ += order_.front().bytes;
  entries_.emplace(key, order_.begin());
  trim_locked();
}

void CheckedFiles::remember_environment(const fs::path& file, const Image* pixels,
                                        std::shared_ptr<const Distribution2D> table) {
  if (!pixels || !table) return;
  const std::optional<std::string> id = identity_of(file);
  if (!id) return;
  const size_t bytes = table->bytes();
  std::lock_guard lock(mu_);
  const auto it = entries_.find(file.string());
  if (it == entries_.end() || it->second->identity != *id || it->second->record.image.get() != pixels) return;
  Entry& e = *it->second;
  if (e.record.environment || e.bytes + bytes > image_budget_) return;
  e.record.environment = std::move(table);
  e.bytes += bytes;
  image_bytes_ += bytes;
  order_.splice(order_.begin(), order_, it->second);
  trim_locked();
}

void CheckedFiles::trim_locked() {
  while (order_.size() > capacity_) {
    image_bytes_ -= order_.back().bytes;
    entries_.erase(order_.back().path);
    order_.pop_back();
  }
  // Pixels (and their tables) of the least recently used files go first; their digests stay.
  for (auto it = order_.rbegin(); image_bytes_ > image_budget_ && it != order_.rend(); ++it) {
    if (!it->record.image) continue;
    image_bytes_ -= it->bytes;
    it->bytes = 0;
    it->record.image.reset();
    it->record.environment.reset();
  }
}

size_t CheckedFiles::size() const {
  std::lock_guard lock(mu_);
  return entries_.size();
}

size_t CheckedFiles::image_bytes() const {
  std::lock_guard lock(mu_);
  return image_bytes_;
}

}  // namespace tessera
