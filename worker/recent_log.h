// The worker's recent log lines, kept so that a failure report or a tile's upload can carry what the worker logged
// about that lease.
#pragma once

#include <spdlog/sinks/base_sink.h>

#include <cstddef>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::worker {

/// A log sink keeping the last `capacity` formatted lines in memory.
class RecentLog final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  /// Keeps at most `capacity` lines.
  explicit RecentLog(size_t capacity = 400) : capacity_(capacity) {}
  /// The last `max_lines` kept lines that contain `key`, oldest first, each cut to at most `max_bytes` bytes.
  std::vector<std::string> lines_with(std::string_view key, size_t max_lines, size_t max_bytes);

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override;
  void flush_() override {}

 private:
  size_t capacity_;
  std::deque<std::string> lines_;
};

/// Attaches a RecentLog to the default logger while it lives (the logger is not replaced).
class RecentLogScope {
 public:
  RecentLogScope();
  ~RecentLogScope();
  RecentLogScope(const RecentLogScope&) = delete;
  RecentLogScope& operator=(const RecentLogScope&) = delete;
  /// The attached log.
  RecentLog& log() { return *log_; }

 private:
  std::shared_ptr<RecentLog> log_;
};

}  // namespace tessera::worker
