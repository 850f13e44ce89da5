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
  using A = Access;
  using R = Resource;
  using S = Room;
  static const std::vector<RouteSpec> table = {
      {Endpoint::healthz, "healthz", "/healthz", R::health, {{"GET", A::open}}},
      {Endpoint::metrics, "metrics", "/metrics", R::health, {{"GET", A::either}}},
      // Which blobs a submission still has to upload.
      {Endpoint::blobs, "blobs", "/v1/blobs", R::blobs, {{"POST", A::submit}}},
      // HEAD and PUT are a submission's; GET is a worker's too.
      {Endpoint::blob, "blob", "/v1/blobs/{sha256}", R::blobs, {{"PUT", A::submit, false, "", S::above_floor}, {"HEAD", A::submit}, {"GET", A::either}}},
      {Endpoint::jobs, "jobs", "/v1/jobs", R::jobs, {{"GET", A::read}, {"POST", A::submit, true, "", S::above_floor}}},
      {Endpoint::job, "job", "/v1/jobs/{id}", R::jobs,
       {{"GET", A::read}, {"PATCH", A::owner, false, "priority"}, {"DELETE", A::owner, false, "purge"}}},
      {Endpoint::job_result, "job_result", "/v1/jobs/{id}/result.exr", R::jobs, {{"GET", A::read}}},
      {Endpoint::job_preview, "job_preview", "/v1/jobs/{id}/preview.png", R::jobs, {{"GET", A::read}}},
      {Endpoint::job_spec, "job_spec", "/v1/jobs/{id}/spec", R::jobs, {{"GET", A::either}}},
      {Endpoint::job_retry, "job_retry", "/v1/jobs/{id}/retry", R::jobs, {{"POST", A::owner, false, "retry"}}},
      {Endpoint::job_pause, "job_pause", "/v1/jobs/{id}/pause", R::jobs, {{"POST", A::owner, false, "pause"}}},
      {Endpoint::job_resume, "job_resume", "/v1/jobs/{id}/resume", R::jobs, {{"POST", A::owner, false, "resume"}}},
      {Endpoint::job_tiles, "job_tiles", "/v1/jobs/{id}/tiles", R::tiles, {{"GET", A::read}}},
      {Endpoint::job_tile_requeue, "job_tile_requeue", "/v1/jobs/{id}/tiles/{n}/requeue", R::tiles,
       {{"POST", A::owner, false, "requeue"}}},
      // A sequence's frames (each a job of its own), a page at a time, and a frame's result by its number.
      {Endpoint::job_frames, "job_frames", "/v1/jobs/{id}/frames", R::jobs, {{"GET", A::read}}},
      {Endpoint::job_frame_result, "job_frame_result", "/v1/jobs/{id}/frames/{n}/result.exr", R::jobs, {{"GET", A::read}}},
      // GET lists the workers (a client's view); POST registers one.
      {Endpoint::workers, "workers", "/v1/workers", R::workers, {{"GET", A::read, false, "workers"}, {"POST", A::worker}}},
      {Endpoint::worker_drain, "worker_drain", "/v1/workers/{wid}/drain", R::workers, {{"POST", A::admin, false, "drain"}}},
      {Endpoint::worker_undrain, "worker_undrain", "/v1/workers/{wid}/undrain", R::workers, {{"POST", A::admin}}},
      {Endpoint::worker_lease, "worker_lease", "/v1/workers/{wid}/lease", R::leases, {{"POST", A::worker, false, "", S::not_full}}},
      {Endpoint::lease_heartbeat, "lease_heartbeat", "/v1/leases/{lease}/heartbeat", R::leases, {{"POST", A::worker}}},
      {Endpoint::lease_result, "lease_result", "/v1/leases/{lease}/result", R::leases, {{"PUT", A::worker, false, "", S::not_full}}},
      {Endpoint::lease_fail, "lease_fail", "/v1/leases/{lease}/fail", R::leases, {{"POST", A::worker}}},
      {Endpoint::lease_release, "lease_release", "/v1/leases/{lease}/release", R::leases, {{"POST", A::worker}}},
      {Endpoint::lease_state, "lease_state", "/v1/leases/{lease}/state", R::leases, {{"GET", A::worker}}},
      {Endpoint::events, "events", "/v1/events", R::events, {{"GET", A::read, false, "events"}}},
      // Who the coordinator takes the caller for, and the trail of control actions.
      {Endpoint::me, "me", "/v1/me", R::users, {{"GET", A::either}}},
      {Endpoint::audit, "audit", "/v1/audit", R::users, {{"GET", A::admin, false, "audit"}}},
      {Endpoint::webhook_deliveries, "webhook_deliveries", "/v1/webhooks/deliveries", R::webhooks,
       {{"GET", A::admin, false, "webhook_deliveries"}}},
      {Endpoint::job_output, "job_output", "/v1/jobs/{id}/outputs/{name}", R::steps, {{"GET", A::read, false, "outputs"}}},
  };
  return table;
}

const MethodSpec* RouteSpec::method(std::string_view name) const {
  for (const MethodSpec& m : methods)
    if (m.name == name) return &m;
  return nullptr;
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
