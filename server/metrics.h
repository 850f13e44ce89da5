// Coordinator metrics in Prometheus text format: scheduler counters, ray throughput and request latencies.
#pragma once

#include "server/scheduler.h"

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace tessera::server {

/// Request latencies by route and recent ray throughput. Thread-safe.
class Metrics {
 public:
  /// Upper bounds (seconds) of the latency histogram's buckets (+Inf is implied).
  static constexpr std::array<double, 10> kBuckets{0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.5, 1, 5};
  /// Window over which tessera_rays_per_second is averaged.
  static constexpr int64_t kRateWindowMs = 30'000;

  /// Records one request's duration under its route label (e.g. "PUT /v1/blobs/{sha256}").
  void observe_request(const std::string& route, double seconds);
  /// Records rays reported at time now_ms.
  void add_rays(uint64_t rays, int64_t now_ms);
  /// Rays per second over the last kRateWindowMs.
  double rays_per_second(int64_t now_ms);
  /// The whole exposition: scheduler counters, lease requests held for work, and what this object recorded.
  std::string prometheus(const SchedulerCounters& counters, int64_t now_ms, std::size_t held_lease_requests = 0);

 private:
  struct Histogram {
    std::array<uint64_t, kBuckets.size()> buckets{};
    uint64_t count = 0;
    double sum = 0;
  };
  double rate_locked(int64_t now_ms);
  std::mutex mu_;
  std::map<std::string, Histogram> requests_;
  std::deque<std::pair<int64_t, uint64_t>> rays_;  // (time, rays) within the window
};

}  // namespace tessera::server
