// Every URL of the farm protocol, once: the route table the coordinator matches requests against, and the builders
// clients make request targets with.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// The endpoints a request target can name.
enum class Endpoint {
  none, healthz, metrics, blobs, blob, jobs, job, job_result, job_preview, job_spec, job_retry, job_pause, job_resume, job_tiles,
  job_tile_requeue, workers, worker_drain, worker_undrain, worker_lease, lease_heartbeat, lease_result, lease_fail,
  lease_release, lease_state, events
};

/// One route: its path pattern ("{name}" segments are its path parameters, at most two) and the methods it accepts.
struct RouteSpec {
  Endpoint endpoint;                       ///< Which endpoint.
  std::string_view pattern;                ///< e.g. "/v1/jobs/{id}/spec".
  std::vector<std::string_view> methods;   ///< e.g. {"GET"}.
};

/// Every route of the protocol.
const std::vector<RouteSpec>& route_table();

/// A request target matched against the table.
struct RouteMatch {
  const RouteSpec* route = nullptr;  ///< nullptr: no route (404).
  std::string param;                 ///< The value of the pattern's first parameter.
  std::string param2;                ///< The value of its second parameter (e.g. the tile of a requeue), if any.
};

/// Matches a request target (query string ignored); empty segments ("//", a trailing slash) never match.
RouteMatch match_route(std::string_view target);

/// The path of an endpoint with its parameters filled in.
std::string path(Endpoint endpoint, std::string_view param = {}, std::string_view param2 = {});

/// Request targets, by name.
namespace routes {
inline std::string healthz() { return path(Endpoint::healthz); }
inline std::string metrics() { return path(Endpoint::metrics); }
inline std::string blobs() { return path(Endpoint::blobs); }
inline std::string blob(std::string_view sha256) { return path(Endpoint::blob, sha256); }
inline std::string jobs() { return path(Endpoint::jobs); }
inline std::string job(std::string_view id) { return path(Endpoint::job, id); }
inline std::string job_purge(std::string_view id) { return path(Endpoint::job, id) + "?purge=true"; }
inline std::string job_result(std::string_view id) { return path(Endpoint::job_result, id); }
inline std::string job_preview(std::string_view id) { return path(Endpoint::job_preview, id); }
inline std::string job_spec(std::string_view id) { return path(Endpoint::job_spec, id); }
inline std::string job_retry(std::string_view id) { return path(Endpoint::job_retry, id); }
inline std::string job_pause(std::string_view id) { return path(Endpoint::job_pause, id); }
inline std::string job_resume(std::string_view id) { return path(Endpoint::job_resume, id); }
inline std::string job_tiles(std::string_view id) { return path(Endpoint::job_tiles, id); }
inline std::string job_tile_requeue(std::string_view id, int64_t tile) {
  return path(Endpoint::job_tile_requeue, id, std::to_string(tile));
}
inline std::string workers() { return path(Endpoint::workers); }
inline std::string worker_drain(std::string_view worker) { return path(Endpoint::worker_drain, worker); }
inline std::string worker_undrain(std::string_view worker) { return path(Endpoint::worker_undrain, worker); }
inline std::string worker_lease(std::string_view worker) { return path(Endpoint::worker_lease, worker); }
inline std::string lease_heartbeat(std::string_view lease) { return path(Endpoint::lease_heartbeat, lease); }
inline std::string lease_result(std::string_view lease) { return path(Endpoint::lease_result, lease); }
inline std::string lease_fail(std::string_view lease) { return path(Endpoint::lease_fail, lease); }
inline std::string lease_release(std::string_view lease) { return path(Endpoint::lease_release, lease); }
inline std::string lease_state(std::string_view lease) { return path(Endpoint::lease_state, lease); }
inline std::string events() { return path(Endpoint::events); }
}  // namespace routes

}  // namespace tessera::protocol
