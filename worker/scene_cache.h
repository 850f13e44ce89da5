// A small least-recently-used cache of built scenes (with their BVH), keyed by job id.
#pragma once

#include <cstddef>
#include <list>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace tessera::worker {

/// Keeps the `capacity` most recently used values; used by one thread.
template <class T>
class LruCache {
 public:
  /// A cache holding at most capacity (>= 1) entries.
  explicit LruCache(size_t capacity) : capacity_(capacity < 1 ? 1 : capacity) {}
  /// The value for key (now the most recently used), or null.
  std::shared_ptr<const T> find(const std::string& key) {
    for (auto it = entries_.begin(); it != entries_.end(); ++it)
      if (it->first == key) {
        entries_.splice(entries_.begin(), entries_, it);
        return entries_.front().second;
      }
    return nullptr;
  }
  /// Stores value under key as the most recently used entry, evicting the least recently used beyond capacity.
  void put(const std::string& key, std::shared_ptr<const T> value) {
    for (auto it = entries_.begin(); it != entries_.end(); ++it)
      if (it->first == key) {
        entries_.erase(it);
        break;
      }
    entries_.emplace_front(key, std::move(value));
    while (entries_.size() > capacity_) entries_.pop_back();
  }
  /// Number of entries.
  size_t size() const { return entries_.size(); }
  /// The keys held, most recently used first.
  std::vector<std::string> keys() const {
    std::vector<std::string> k;
    for (const auto& e : entries_) k.push_back(e.first);
    return k;
  }

 private:
  size_t capacity_;
  std::list<std::pair<std::string, std::shared_ptr<const T>>> entries_;
};

}  // namespace tessera::worker
