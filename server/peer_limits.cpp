#include "server/peer_limits.h"

namespace tessera::server {

namespace {
constexpr auto kWindow = std::chrono::minutes(1);
}

void RefusalRate::roll(Clock::time_point now) {
  if (now - window_start_ < kWindow) return;
  window_start_ = now;
  counts_.clear();
}

void RefusalRate::note(const boost::asio::ip::address& address, Clock::time_point now) {
  if (per_minute_ == 0) return;
  std::lock_guard lock(mu_);
  roll(now);
  const std::string key = address.to_string();
  if (auto it = counts_.find(key); it != counts_.end()) ++it->second;
  else if (counts_.size() < kMaxAddresses) counts_.emplace(key, 1);
}

int RefusalRate::blocked_for(const boost::asio::ip::address& address, Clock::time_point now) {
  if (per_minute_ == 0) return 0;
  std::lock_guard lock(mu_);
  roll(now);
  const auto it = counts_.find(address.to_string());
  if (it == counts_.end() || it->second < per_minute_) return 0;
  const auto left = std::chrono::ceil<std::chrono::seconds>(window_start_ + kWindow - now).count();
  return int(std::max<decltype(left)>(left, 1));
}

}  // namespace tessera::server
