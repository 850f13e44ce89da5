// Exponential backoff with jitter, and sleeping that a stop request can cut short.
#pragma once

#include <algorithm>
#include <chrono>
#include <functional>
#include <random>
#include <thread>

namespace tessera::client {

/// Delays that double from `initial` up to `max`, each drawn uniformly from [delay/2, delay] so that many clients
/// retrying together spread out.
class Backoff {
 public:
  /// A backoff starting at initial and capped at max.
  Backoff(std::chrono::milliseconds initial, std::chrono::milliseconds max)
      : initial_(initial), max_(max), current_(initial), rng_(std::random_device{}()) {}
  /// The next delay (jittered); grows the base delay for the call after.
  std::chrono::milliseconds next() {
    const auto base = current_;
    current_ = std::min(max_, current_ * 2);
    std::uniform_int_distribution<long long> pick(base.count() / 2, base.count());
    return std::chrono::milliseconds(pick(rng_));
  }
  /// Back to the initial delay (after a success).
  void reset() { current_ = initial_; }
  /// True while no delay has been handed out since construction or the last reset.
  bool at_start() const { return current_ == initial_; }

 private:
  std::chrono::milliseconds initial_, max_, current_;
  std::mt19937_64 rng_;
};

/// Sleeps for d, waking every 5 ms to ask stop(); returns false when stop() said true (the sleep was cut short). The
/// stop flags it watches are set by signal handlers, which cannot wake a waiting thread: the short slice is what
/// lets a stopped worker exit within milliseconds.
inline bool sleep_unless(std::chrono::milliseconds d, const std::function<bool()>& stop) {
  const auto end = std::chrono::steady_clock::now() + d;
  while (true) {
    if (stop && stop()) return false;
    const auto now = std::chrono::steady_clock::now();
    if (now >= end) return true;
    std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(end - now, std::chrono::milliseconds(5)));
  }
}

}  // namespace tessera::client
