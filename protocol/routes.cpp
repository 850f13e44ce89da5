#include "protocol/routes.h"

#include <stdexcept>

namespace tessera::protocol {

namespace {

// The path's segments after the leading '/', or nothing for a path that does not start with '/'.
std::vector<std::string_view> segments(std::string_view path) {
  std::vector<std::string_view> out;
  if (path.empty() || path[0] != '/') return out;
  size_t i = 1;
  while (true) {
    const size_t j = path.find('/', i);
    out.push_back(path.substr(i, j == std::string_view::npos ? std::string_view::npos : j - i));
    if (j == std::string_view::npos) break;
    i = j + 1;
  }
  return out;
}

bool is_param(std::string_view segment) { return segment.size() > 2 && segment.front() == '{' && segment.back() == '}'; }

}  // namespace

const std::vector<RouteSpec>& route_table() {
  static const std::vector<RouteSpec> table = {
      {Endpoint::healthz, "/healthz", {"GET"}},
      {Endpoint::metrics, "/metrics", {"GET"}},
      {Endpoint::blobs, "/v1/blobs", {"POST"}},
      {Endpoint::blob, "/v1/blobs/{sha256}", {"PUT", "HEAD", "GET"}},
      {Endpoint::jobs, "/v1/jobs", {"GET", "POST"}},
      {Endpoint::job, "/v1/jobs/{id}", {"GET", "PATCH", "DELETE"}},
      {Endpoint::job_result, "/v1/jobs/{id}/result.exr", {"GET"}},
      {Endpoint::job_preview, "/v1/jobs/{id}/preview.png", {"GET"}},
      {Endpoint::job_spec, "/v1/jobs/{id}/spec", {"GET"}},
      {Endpoint::job_retry, "/v1/jobs/{id}/retry", {"POST"}},
      {Endpoint::job_pause, "/v1/jobs/{id}/pause", {"POST"}},
      {Endpoint::job_resume, "/v1/jobs/{id}/resume", {"POST"}},
      {Endpoint::job_tiles, "/v1/jobs/{id}/tiles", {"GET"}},
      {Endpoint::job_tile_requeue, "/v1/jobs/{id}/tiles/{n}/requeue", {"POST"}},
      {Endpoint::workers, "/v1/workers", {"GET", "POST"}},
      {Endpoint::worker_drain, "/v1/workers/{wid}/drain", {"POST"}},
      {Endpoint::worker_undrain, "/v1/workers/{wid}/undrain", {"POST"}},
      {Endpoint::worker_lease, "/v1/workers/{wid}/lease", {"POST"}},
      {Endpoint::lease_heartbeat, "/v1/leases/{lease}/heartbeat", {"POST"}},
      {Endpoint::lease_result, "/v1/leases/{lease}/result", {"PUT"}},
      {Endpoint::lease_fail, "/v1/leases/{lease}/fail", {"POST"}},
      {Endpoint::lease_release, "/v1/leases/{lease}/release", {"POST"}},
      {Endpoint::lease_state, "/v1/leases/{lease}/state", {"GET"}},
      {Endpoint::events, "/v1/events", {"GET"}},
  };
  return table;
}

RouteMatch match_route(std::string_view target) {
  const std::vector<std::string_view> got = segments(target.substr(0, target.find('?')));
  if (got.empty()) return {};
  for (std::string_view s : got)
    if (s.empty()) return {};  // "//" or a trailing slash
  for (const RouteSpec& r : route_table()) {
    const std::vector<std::string_view> want = segments(r.pattern);
    if (want.size() != got.size()) continue;
    RouteMatch m{&r, {}, {}};
    int params = 0;
    for (size_t i = 0; i < want.size() && m.route; ++i) {
      if (is_param(want[i])) (params++ == 0 ? m.param : m.param2) = got[i];
      else if (want[i] != got[i]) m.route = nullptr;
    }
    if (m.route) return m;
  }
  return {};
}

std::string path(Endpoint endpoint, std::string_view param, std::string_view param2) {
  for (const RouteSpec& r : route_table()) {
    if (r.endpoint != endpoint) continue;
    std::string out;
    int params = 0;
    for (std::string_view s : segments(r.pattern)) {
      out += '/';
      out += is_param(s) ? (params++ == 0 ? param : param2) : s;
    }
    return out;
  }
  throw std::invalid_argument("no route for this endpoint");
}

}  // namespace tessera::protocol
