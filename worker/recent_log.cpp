#include "worker/recent_log.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace tessera::worker {

void RecentLog::sink_it_(const spdlog::details::log_msg& msg) {
  spdlog::memory_buf_t buf;
  formatter_->format(msg, buf);
  std::string line(buf.data(), buf.size());
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  lines_.push_back(std::move(line));
  if (lines_.size() > capacity_) lines_.pop_front();
}

std::vector<std::string> RecentLog::lines_with(std::string_view key, size_t max_lines, size_t max_bytes) {
  std::lock_guard lock(mutex_);
  std::vector<std::string> out;
  for (auto it = lines_.rbegin(); it != lines_.rend() && out.size() < max_lines; ++it)
    if (it->find(key) != std::string::npos) out.push_back(it->substr(0, max_bytes));
  std::reverse(out.begin(), out.end());
  return out;
}

RecentLogScope::RecentLogScope() : log_(std::make_shared<RecentLog>()) {
  log_->set_level(spdlog::level::trace);
  spdlog::default_logger()->sinks().push_back(log_);
}

RecentLogScope::~RecentLogScope() {
  auto& sinks = spdlog::default_logger()->sinks();
  sinks.erase(std::remove(sinks.begin(), sinks.end(), log_), sinks.end());
}

}  // namespace tessera::worker
