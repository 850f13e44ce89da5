#include "server/registration_limit.h"

#include <algorithm>
#include <cmath>

namespace tessera::server {

namespace {
// The bucket counts in 1/60000 of a registration, so that a rate of N a minute adds exactly N of them a millisecond.
constexpr double kUnitsPerRegistration = 60'000.0;
}  // namespace

RegistrationLimit::RegistrationLimit(double per_minute)
    : per_ms_(std::max(0.0, per_minute)),
      capacity_(std::max(1.0, per_minute) * kUnitsPerRegistration),
      tokens_(capacity_) {}

int64_t RegistrationLimit::take(int64_t now_ms) {
  if (per_ms_ <= 0) return 0;
  std::lock_guard lock(mu_);
  if (last_ && now_ms > *last_) tokens_ = std::min(capacity_, tokens_ + double(now_ms - *last_) * per_ms_);
  if (!last_ || now_ms > *last_) last_ = now_ms;  // a clock that stepped back adds nothing
  if (tokens_ >= kUnitsPerRegistration) {
    tokens_ -= kUnitsPerRegistration;
    return 0;
  }
  return std::max<int64_t>(1, int64_t(std::ceil((kUnitsPerRegistration - tokens_) / per_ms_)));
}

}  // namespace tessera::server
