// Every URL of the farm protocol, once: the route table the coordinator matches requests against (with each method's
// access rule, admission and the resource that answers it), and the builders clients make request targets with.
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
  job_tile_requeue, job_frames, job_frame_result, workers, worker_drain, worker_undrain, worker_lease, lease_heartbeat, lease_result, lease_fail,
  lease_release, lease_state, events, me, audit, webhook_deliveries, job_output
};

/// The credential a request must carry (docs/protocol.md, "Access"); protocol/access.h says which roles each admits.
/// The client token admits every client-side access (read, submit, owner, admin); the worker token, worker.
enum class Access {
  open,    ///< No credential (health probes).
  read,    ///< A client's view (jobs, results, workers, events): viewer, user, admin.
  submit,  ///< New work (jobs, blob uploads): user, admin.
  owner,   ///< A control of one job (pause, cancel, purge...): its owner with the user role, or an admin.
  admin,   ///< The farm's controls (drain a worker, the audit trail): admin.
  worker,  ///< A worker's own requests (register, lease, heartbeat, upload tiles, fail, release): worker.
  either,  ///< Any credential (read-only views both sides use: blob downloads, job specs, metrics).
};

/// What free space on the coordinator's data folder a method needs before it is tried (docs/operations.md, "Disk
/// full"); without it the answer is 507 Insufficient Storage with a sentence.
enum class Room {
  any,          ///< Answered whatever the disk holds (reads; a small write that then fails for want of space is 507).
  not_full,     ///< Refused while the disk is full: the writes that finish admitted work (leases, tile uploads).
  above_floor,  ///< Refused while the free space is below `serve --min-free-disk` or the disk is full: new work
                ///< (submissions, blob uploads).
};

/// The coordinator's resource handler that answers a route.
enum class Resource { health, blobs, jobs, tiles, workers, leases, events, users, webhooks, steps };

/// One method a route accepts.
struct MethodSpec {
  std::string_view name;        ///< e.g. "GET".
  Access access;                ///< The token it needs.
  /// Answered after a turn in the submission queue (a scene load: server/admission_handler.h), not at once.
  bool admission;
  std::string_view capability;  ///< The web monitor's control it enables (capabilities.json), "" none.
  Room room;                    ///< The free space it needs before it is tried.

  MethodSpec(std::string_view name, Access access, bool admission = false, std::string_view capability = {},
             Room room = Room::any)
      : name(name), access(access), admission(admission), capability(capability), room(room) {}
};

/// One route: its path pattern ("{name}" segments are its path parameters, at most two) and the methods it accepts.
struct RouteSpec {
  Endpoint endpoint;                 ///< Which endpoint.
  std::string_view name;             ///< The endpoint's name, e.g. "job_spec" (the monitor's route names).
  std::string_view pattern;          ///< e.g. "/v1/jobs/{id}/spec".
  Resource resource;                 ///< Who answers it.
  std::vector<MethodSpec> methods;   ///< e.g. {{"GET", Access::either}}.

  /// The method called `method`, or nullptr when the route does not accept it.
  const MethodSpec* method(std::string_view method) const;
};

/// Every route of the protocol.
const std::vector<RouteSpec>& route_table();

/// A request target matched against the table.
struct RouteMatch {
  const RouteSpec* route = nullptr;  ///< nullptr: no route (404).
  std::string param;                 ///< The value of the pattern's first parameter.
  std::string param2;                ///< The value of its second parameter (e.g. the tile of a requeue), if any.

  /// The matched endpoint (none when no route matched).
  Endpoint endpoint() const { return route ? route->endpoint : Endpoint::none; }
  /// The matched route's method called `method`; nullptr when no route matched or it does not accept the method.
  const MethodSpec* method(std::string_view method) const { return route ? route->method(method) : nullptr; }
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
inline std::string job_frames(std::string_view id) { return path(Endpoint::job_frames, id); }
inline std::string job_frame_result(std::string_view id, int64_t frame) {
  return path(Endpoint::job_frame_result, id, std::to_string(frame));
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
inline std::string me() { return path(Endpoint::me); }
inline std::string audit() { return path(Endpoint::audit); }
inline std::string webhook_deliveries() { return path(Endpoint::webhook_deliveries); }
inline std::string job_output(std::string_view id, std::string_view name) { return path(Endpoint::job_output, id, name); }
}  // namespace routes

}  // namespace tessera::protocol
