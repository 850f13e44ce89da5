// Limits on peers that have not shown a credential: how many idle connections one address may keep when every slot is
// taken, and how many token refusals one address may draw in a minute.
#pragma once

#include <boost/asio/ip/address.hpp>

#include <chrono>
#include <cstddef>
#include <mutex>
#include <string>
#include <unordered_map>

namespace tessera::server {

/// Limits on unauthenticated peers, per remote address.
struct PeerLimitOptions {
  /// Connections one address may hold before an authenticated request; when every slot is taken, a new connection
  /// closes the oldest such connection of the address that holds the most of them beyond this (0: a quarter of the
  /// connection limit).
  std::size_t anonymous_per_address = 0;
  /// Token refusals (401 and 403) one address may draw per minute; beyond it, its new connections are answered 429
  /// until the minute ends (0: no limit).
  std::size_t refusals_per_minute = 600;
};

/// Counts token refusals per address in one-minute windows; thread-safe.
class RefusalRate {
 public:
  using Clock = std::chrono::steady_clock;
  /// At most `per_minute` refusals per address and minute (0: unlimited).
  explicit RefusalRate(std::size_t per_minute) : per_minute_(per_minute) {}
  /// Counts one refusal for `address`.
  void note(const boost::asio::ip::address& address, Clock::time_point now);
  /// Whole seconds until `address` may connect again; 0 when it may now.
  int blocked_for(const boost::asio::ip::address& address, Clock::time_point now);

 private:
  void roll(Clock::time_point now);  // starts a new window when the current one is over; needs mu_

  // Addresses counted per window at most; more distinct ones in one minute go uncounted.
  static constexpr std::size_t kMaxAddresses = 65536;
  std::size_t per_minute_;
  std::mutex mu_;
  Clock::time_point window_start_{};
  std::unordered_map<std::string, std::size_t> counts_;
};

}  // namespace tessera::server
