// The farm protocol's front door (docs/protocol.md): matches a request to its endpoint, checks its token and body
// limit, hands it to that resource's handler and turns refusals into error answers. Knows HTTP messages, not sockets.
#pragma once

#include "protocol/messages.h"
#include "protocol/routes.h"
#include "server/audit_trail.h"
#include "server/auth.h"
#include "server/coordinator_store.h"
#include "server/log_limit.h"
#include "server/blobs_handler.h"
#include "server/collector.h"
#include "server/disk_space.h"
#include "server/event_bus.h"
#include "server/events_handler.h"
#include "server/farm_events.h"
#include "server/http_server.h"
#include "server/job_service.h"
#include "server/jobs_handler.h"
#include "server/lease_waiters.h"
#include "server/leases_handler.h"
#include "server/metrics.h"
#include "server/route.h"
#include "server/health_handler.h"
#include "server/scheduler.h"
#include "server/steps/outputs_handler.h"
#include "server/steps/step_runner.h"
#include "server/storage.h"
#include "server/tiles_handler.h"
#include "server/users_handler.h"
#include "server/webhooks_handler.h"
#include "server/workers_handler.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// Size limits and timings the API announces and enforces (with the admission limits of a job it inherits).
struct ApiOptions : AdmissionLimits {
  std::size_t json_limit = std::size_t(16) << 20;    ///< JSON request bodies.
  std::size_t blob_limit = std::size_t(256) << 20;   ///< Blob uploads.
  std::size_t result_limit = std::size_t(64) << 20;  ///< Tile result uploads.
  int heartbeat_seconds = protocol::kDefaultHeartbeatSeconds;  ///< Heartbeat interval announced to workers.
  AccessTokens tokens;  ///< Bearer tokens and the users file (none on a side: that side's endpoints are open).
  RetentionOptions retention;                        ///< How long finished jobs and unreferenced blobs are kept.
  double registrations_per_minute = 600;  ///< Worker registrations taken a minute; more get 429 (0: no limit).
  WebhookLog* webhook_log = nullptr;  ///< The delivery log GET /v1/webhooks/deliveries lists (none: an empty list).
  StepOptions steps;  ///< How the steps after the merge run (the movie step's ffmpeg).
};

/// The endpoints a request target can name (protocol/routes.h).
using RouteId = protocol::Endpoint;

/// The token an endpoint needs for a method (the route table's, protocol/routes.h); for a method the endpoint does not
/// accept, that of its first method.
Access route_access(RouteId route, http::verb method);

/// The HTTP handler implementing docs/protocol.md.
class Api final : public RoutedHandler {
 public:
  /// An API over the given state, publishing changes through `events` and streaming `bus` at GET /v1/events, refusing
  /// work by the free space `disk` holds (and noting there when a write found it full); all references must outlive
  /// it. `background` runs the next lease an upload asked for, `results` writes finished jobs' results (each by
  /// default at once). Throws std::runtime_error for a users file it cannot read.
  Api(Scheduler& scheduler, BlobStore& blobs, CoordinatorStore& store, Metrics& metrics, ClockMs clock,
      ApiOptions options, EventBus& bus, FarmEvents& events, DiskSpace& disk, Background background = {},
      Background results = {});
  ~Api() override;
  Api(const Api&) = delete;
  Api& operator=(const Api&) = delete;
  /// True when the header's credential is one the coordinator knows (or none is required).
  bool authenticated(const http::request_header<>& header) noexcept override;
  std::size_t routed_body_limit(const http::request_header<>& header, const Route& route) override;
  /// The refusal of a token that does not let the request's method on its route (401/403), before the body is read.
  std::optional<HttpResponse> routed_early_response(const http::request_header<>& header, const Route& route) noexcept override;
  /// Answers a request; GET /v1/events (once its token is checked) with a stream; a result upload's answer comes
  /// from the thread that flushed its tile.
  void handle_routed(HttpRequest&& request, const Route& route, Reply done) noexcept override;
  /// After a restart: finishes jobs whose every tile was stored but whose result was not written yet.
  void recover() {
    jobs_.recover();
    steps_.resume();
  }
  /// Purges finished jobs and audit entries past their retention time and collects unreferenced blobs (see
  /// Collector::sweep).
  SweepReport sweep();
  /// Re-reads the users file: the scheduler takes the new shares, and open event streams of removed users end.
  /// Returns how many users it holds; throws std::runtime_error keeping the users it had.
  size_t reload_users();
  /// True when both the client and the worker side need a credential.
  bool credentials_complete() const { return credentials_.complete(); }
  /// Writes the results that waited for disk space; false when one still does not fit (JobService::write_waiting_results).
  bool write_waiting_results() { return jobs_.write_waiting_results(); }
  /// Answers every lease request held for work with "no work", and later ones at once (at shutdown, so that the
  /// transport's in-flight requests end).
  void stop_holding_leases() { lease_waiters_->close(); }

 private:
  /// The refusal of the request's credential on its route and method (both matched), or nothing when it may pass
  /// (then sets `caller` and `credential`, when given, to whom it stands for).
  std::optional<HttpResponse> check_access(const Route& route, const http::request_header<>& header,
                                           Caller* caller = nullptr, std::string* credential = nullptr);
  /// The 403 of a job control on a job of another user by a caller that may act only on its own, or nothing.
  std::optional<HttpResponse> check_owner(const Route& route, const HttpRequest& request, const Caller& caller);
  /// Passes the users' weights and caps to the scheduler.
  void share_farm();
  /// The 404 (no route) or 405 (no such method on the route, with Allow) for a request without a method entry.
  static HttpResponse unrouted(const Route& route, const http::request_header<>& header);
  /// Checks the routed request and hands it to its resource handler; `send` gets the answer once (maybe later).
  void answer(HttpRequest&& request, const Route& route, std::function<void(HttpReply)> send) noexcept;
  /// The answer to a refused request: 400, the ApiError's status, 507 for a write the disk had no room for (noted in
  /// disk_), or 500 (logged).
  HttpResponse refusal(std::exception_ptr error, const HttpRequest& request) const;
  ResourceHandler& handler_for(protocol::Resource resource);

  Metrics& metrics_;
  DiskSpace& disk_;
  ApiOptions opt_;
  Credentials credentials_;  // opt_.tokens' digests and the users file
  LogLimit refusal_log_{10, std::chrono::minutes(1)};  // the 401 and 403 lines
  Scheduler& sched_;                              // notes new work to lease_waiters_ while this lives
  std::unique_ptr<LeaseWaiters> lease_waiters_;  // ended first in ~Api, while what its requests answer through lives
  StepRunner steps_;  // before jobs_, which runs steps on it: ended after it
  JobService jobs_;
  Collector collector_;
  AuditTrail audit_;
  JobsHandler jobs_handler_;
  TilesHandler tiles_handler_;
  LeasesHandler leases_handler_;
  WorkersHandler workers_handler_;
  BlobsHandler blobs_handler_;
  HealthHandler health_handler_;
  EventsHandler events_handler_;
  UsersHandler users_handler_;
  WebhooksHandler webhooks_handler_;
  OutputsHandler outputs_handler_;
};

}  // namespace tessera::server
