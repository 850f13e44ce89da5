// A histogram of durations as Prometheus reads one: cumulative buckets, a count and a sum.
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace tessera::server {

/// Durations counted into fixed buckets. Not thread-safe: its owner locks.
struct LatencyHistogram {
  /// Upper bounds (seconds) of the buckets (+Inf is implied).
  static constexpr std::array<double, 10> kBuckets{0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.5, 1, 5};

  /// Durations at or below each bound (cumulative, as Prometheus reads them).
  std::array<uint64_t, kBuckets.size()> buckets{};
  uint64_t count = 0;  ///< Every duration counted.
  double sum = 0;      ///< Their sum in seconds.

  /// Counts one duration.
  void observe(double seconds);
  /// The sample lines of metric `name` (its _bucket, _sum and _count) with `labels` (e.g. `route="GET /healthz"`, or
  /// empty for none).
  std::string prometheus(const std::string& name, const std::string& labels) const;
};

}  // namespace tessera::server
