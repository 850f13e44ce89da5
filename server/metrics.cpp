#include "server/metrics.h"

#include <spdlog/fmt/fmt.h>

namespace tessera::server {

void Metrics::observe_request(const std::string& route, double seconds) {
  std::lock_guard lock(mu_);
  requests_[route].observe(seconds);
}

void Metrics::add_rays(uint64_t rays, int64_t now_ms) {
  if (rays == 0) return;
  std::lock_guard lock(mu_);
  rays_.emplace_back(now_ms, rays);
}

double Metrics::rate_locked(int64_t now_ms) {
  while (!rays_.empty() && rays_.front().first < now_ms - kRateWindowMs) rays_.pop_front();
  uint64_t sum = 0;
  for (const auto& [t, n] : rays_) sum += n;
  return double(sum) / (double(kRateWindowMs) / 1000.0);
}

double Metrics::rays_per_second(int64_t now_ms) {
  std::lock_guard lock(mu_);
  return rate_locked(now_ms);
}

namespace {

std::string escape_label(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

}  // namespace

std::string Metrics::prometheus(const SchedulerCounters& c, int64_t now_ms, std::size_t held_lease_requests,
                                const std::optional<StoreStats>& store) {
  std::string out;
  out += "# HELP tessera_jobs Jobs by state.\n# TYPE tessera_jobs gauge\n";
  for (const auto& [state, n] : c.jobs) out += fmt::format("tessera_jobs{{state=\"{}\"}} {}\n", to_string(state), n);
  out += "# HELP tessera_tiles_rendered_total Tiles merged into job images.\n# TYPE tessera_tiles_rendered_total counter\n";
  out += fmt::format("tessera_tiles_rendered_total {}\n", c.tiles_rendered);
  out += "# HELP tessera_lease_expiries_total Leases that expired and returned their tile to pending.\n"
         "# TYPE tessera_lease_expiries_total counter\n";
  out += fmt::format("tessera_lease_expiries_total {}\n", c.lease_expiries);
  out += "# HELP tessera_rays_total Rays reported by workers.\n# TYPE tessera_rays_total counter\n";
  out += fmt::format("tessera_rays_total {}\n", c.rays);
  out += "# HELP tessera_workers Registered workers.\n# TYPE tessera_workers gauge\n";
  out += fmt::format("tessera_workers {}\n", c.workers);
  out += "# HELP tessera_leases Live leases.\n# TYPE tessera_leases gauge\n";
  out += fmt::format("tessera_leases {}\n", c.active_leases);
  out += "# HELP tessera_lease_requests_held Lease requests held until a tile is leasable (idle workers).\n"
         "# TYPE tessera_lease_requests_held gauge\n";
  out += fmt::format("tessera_lease_requests_held {}\n", held_lease_requests);
  std::lock_guard lock(mu_);
  out += "# HELP tessera_rays_per_second Rays per second over the last 30 seconds.\n# TYPE tessera_rays_per_second gauge\n";
  out += fmt::format("tessera_rays_per_second {}\n", rate_locked(now_ms));
  out += "# HELP tessera_http_request_duration_seconds Request handling time by route.\n"
         "# TYPE tessera_http_request_duration_seconds histogram\n";
  for (const auto& [route, h] : requests_)
    out += h.prometheus("tessera_http_request_duration_seconds", "route=\"" + escape_label(route) + "\"");
  if (store) {
    out += "# HELP tessera_store_flush_duration_seconds Flushes of the store to the disk (the pixel files written since"
           " the last, then the database's log), each acknowledging the writes before it.\n"
           "# TYPE tessera_store_flush_duration_seconds histogram\n";
    out += store->flushes.prometheus("tessera_store_flush_duration_seconds", "");
    out += "# HELP tessera_store_log_pages_total Database pages written to the write-ahead log.\n"
           "# TYPE tessera_store_log_pages_total counter\n";
    out += fmt::format("tessera_store_log_pages_total {}\n", store->log_pages);
  }
  return out;
}

}  // namespace tessera::server
