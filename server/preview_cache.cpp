#include "server/preview_cache.h"

namespace tessera::server {

PreviewCache::PreviewCache(size_t max_bytes) : max_bytes_(max_bytes) {}

Png PreviewCache::find(const std::string& job, const std::string& version) {
  std::lock_guard lock(mu_);
  const auto it = entries_.find(job);
  if (it == entries_.end() || it->second->version != version) return nullptr;
  order_.splice(order_.begin(), order_, it->second);
  return it->second->png;
}

void PreviewCache::put(const std::string& job, const std::string& version, Png png) {
  std::lock_guard lock(mu_);
  if (const auto it = entries_.find(job); it != entries_.end()) erase_locked(it);
  if (!png || png->size() > max_bytes_) return;
  bytes_ += png->size();
  order_.push_front(Entry{job, version, std::move(png)});
  entries_.emplace(job, order_.begin());
  while (bytes_ > max_bytes_) erase_locked(entries_.find(order_.back().job));
}

void PreviewCache::erase(const std::string& job) {
  std::lock_guard lock(mu_);
  if (const auto it = entries_.find(job); it != entries_.end()) erase_locked(it);
}

void PreviewCache::erase_locked(std::unordered_map<std::string, std::list<Entry>::iterator>::iterator it) {
  bytes_ -= it->second->png->size();
  order_.erase(it->second);
  entries_.erase(it);
}

size_t PreviewCache::size() const {
  std::lock_guard lock(mu_);
  return entries_.size();
}

size_t PreviewCache::bytes() const {
  std::lock_guard lock(mu_);
  return bytes_;
}

}  // namespace tessera::server
