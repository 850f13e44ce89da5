// Jobs' preview PNGs kept once encoded: a preview is asked for again and again (the monitor polls it) while the job's
// pixels change only when a tile lands, so each job's latest preview is kept under the version of the pixels it
// shows and served again until that version changes, within a byte budget.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

namespace tessera::server {

/// A PNG as kept and served.
using Png = std::shared_ptr<const std::vector<uint8_t>>;

/// One preview per job, each with the version of the job's pixels it shows (any text that changes when they do).
/// Thread-safe; keeps at most `max_bytes` of PNGs, forgetting the least recently used first.
class PreviewCache {
 public:
  /// An empty cache that keeps up to `max_bytes` bytes of PNGs.
  explicit PreviewCache(size_t max_bytes = size_t(32) << 20);

  /// The job's preview if it was kept for this very version (now the most recently used); else null.
  Png find(const std::string& job, const std::string& version);

  /// Keeps `png` as the job's preview at `version`, in place of the one kept for it before; a PNG larger than the
  /// whole budget is not kept.
  void put(const std::string& job, const std::string& version, Png png);

  /// Forgets the job's preview (a purged job's, say).
  void erase(const std::string& job);

  /// Previews kept.
  size_t size() const;
  /// Bytes of the PNGs kept.
  size_t bytes() const;

 private:
  struct Entry {
    std::string job;
    std::string version;
    Png png;
  };
  void erase_locked(std::unordered_map<std::string, std::list<Entry>::iterator>::iterator it);

  size_t max_bytes_;
  mutable std::mutex mu_;
  std::list<Entry> order_;  // most recently used first
  std::unordered_map<std::string, std::list<Entry>::iterator> entries_;  // by job
  size_t bytes_ = 0;
};

}  // namespace tessera::server
