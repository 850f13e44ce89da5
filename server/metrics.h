// Coordinator metrics in Prometheus text format: scheduler counters, ray throughput, request latencies and the
// store's disk costs.
#pragma once

#include "server/coordinator_store.h"
#include "server/latency_histogram.h"
#include "server/scheduler.h"

#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

namespace tessera::server {

/// Request latencies by route and recent ray throughput. Thread-safe.
class Metrics {
 public:
  /// Window over which tessera_rays_per_second is averaged.
  static constexpr int64_t kRateWindowMs = 30'000;

  /// Records one request's duration under its route label (e.g. "PUT /v1/blobs/{sha256}").
  void observe_request(const std::string& route, double seconds);
  /// Records rays reported at time now_ms.
  void add_rays(uint64_t rays, int64_t now_ms);
  /// Rays per second over the last kRateWindowMs.
  double rays_per_second(int64_t now_ms);
  /// The whole exposition: scheduler counters, lease requests held for work, the store's disk costs (none for a store
  /// in memory), and what this object recorded.
  std::string prometheus(const SchedulerCounters& counters, int64_t now_ms, std::size_t held_lease_requests = 0,
                         const std::optional<StoreStats>& store = std::nullopt);

 private:
  double rate_locked(int64_t now_ms);
  std::mutex mu_;
  std::map<std::string, LatencyHistogram> requests_;
  std::deque<std::pair<int64_t, uint64_t>> rays_;  // (time, rays) within the window
};

}  // namespace tessera::server
