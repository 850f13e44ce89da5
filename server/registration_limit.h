// How fast workers may register (serve --max-registrations-per-minute): a token bucket that holds up to a minute's
// registrations and refills at the configured rate. There is one worker token, so one bucket for the coordinator.
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>

namespace tessera::server {

/// A token bucket of registrations. Thread-safe.
class RegistrationLimit {
 public:
  /// At most `per_minute` registrations a minute on average, up to a minute's worth (at least one) at once; a rate of
  /// 0 or less sets no limit.
  explicit RegistrationLimit(double per_minute);

  /// Takes one registration at `now_ms` (any clock that does not jump, e.g. the coordinator's): 0 when it may go
  /// ahead, else the milliseconds until the next one may (and nothing is taken).
  int64_t take(int64_t now_ms);

 private:
  const double per_ms_;    // units (1/60000 of a registration) added per millisecond (0: no limit)
  const double capacity_;  // the most units the bucket holds
  std::mutex mu_;
  double tokens_;                 // units in the bucket (mu_)
  std::optional<int64_t> last_;   // when tokens_ was last brought up to date (mu_)
};

}  // namespace tessera::server
