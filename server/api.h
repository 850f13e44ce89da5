// The farm protocol's front door (docs/protocol.md): matches a request to its endpoint, checks its token and body
// limit, hands it to that resource's handler and turns refusals into error answers. Knows HTTP messages, not sockets.
#pragma once

#include "protocol/messages.h"
#include "protocol/routes.h"
#include "server/auth.h"
#include "server/blobs_handler.h"
#include "server/collector.h"
#include "server/event_bus.h"
#include "server/events_handler.h"
#include "server/farm_events.h"
#include "server/http_server.h"
#include "server/job_service.h"
#include "server/jobs_handler.h"
#include "server/lease_waiters.h"
#include "server/leases_handler.h"
#include "server/metrics.h"
#include "server/health_handler.h"
#include "server/scheduler.h"
#include "server/storage.h"
#include "server/tiles_handler.h"
#include "server/workers_handler.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// Size limits and timings the API announces and enforces.
struct ApiOptions {
  std::size_t json_limit = std::size_t(16) << 20;    ///< JSON request bodies.
  std::size_t blob_limit = std::size_t(256) << 20;   ///< Blob uploads.
  std::size_t result_limit = std::size_t(64) << 20;  ///< Tile result uploads.
  int heartbeat_seconds = protocol::kDefaultHeartbeatSeconds;  ///< Heartbeat interval announced to workers.
  AccessTokens tokens;                               ///< Bearer tokens (empty: that side's endpoints are open).
  int64_t max_queued_jobs = 1000;                    ///< Queued plus running jobs; more submissions get 429.
  int retry_after_seconds = 30;                      ///< Retry-After announced with 429.
  uint64_t max_job_pixels = uint64_t(1) << 26;       ///< width x height of one job (the merged image lives in memory).
  double max_job_samples = 4e10;                     ///< width x height x spp (x max_spp when adaptive) of one job.
  RetentionOptions retention;                        ///< How long finished jobs and unreferenced blobs are kept.
};

/// The endpoints a request target can name (protocol/routes.h).
using RouteId = protocol::Endpoint;

/// A matched request target.
struct Route {
  RouteId id = RouteId::none;          ///< Which endpoint (none: 404).
  std::string param;                   ///< The id or hash in the path.
  std::string name;                    ///< Route label for logs and metrics, e.g. "GET /v1/jobs/{id}".
  std::vector<http::verb> methods;     ///< Methods the endpoint accepts.
};

/// Matches a request target (query string ignored) to an endpoint.
Route match_route(std::string_view target);

/// The token an endpoint needs for a method (see docs/protocol.md, "Access").
Access route_access(RouteId route, http::verb method);

/// The HTTP handler implementing docs/protocol.md.
class Api final : public HttpHandler {
 public:
  /// An API over the given state, publishing changes through `events` and streaming `bus` at GET /v1/events; all
  /// references must outlive it.
  Api(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock, ApiOptions options,
      EventBus& bus, FarmEvents& events, Background background = {});
  ~Api() override;
  Api(const Api&) = delete;
  Api& operator=(const Api&) = delete;
  std::size_t body_limit(const http::request_header<>& header) override;
  std::optional<HttpResponse> early_response(const http::request_header<>& header) noexcept override;
  /// Answers a request, waiting for an answer given later (a result upload waits for its flush).
  HttpResponse handle(HttpRequest&& request) noexcept override;
  /// As handle(), but GET /v1/events (once its token is checked) is answered with a stream.
  HttpReply reply(HttpRequest&& request) noexcept override;
  /// As reply(), without waiting: a result upload's answer comes from the thread that flushed its tile.
  void handle_async(HttpRequest&& request, Reply done) noexcept override;
  /// After a restart: finishes jobs whose every tile was stored but whose result was not written yet.
  void recover() { jobs_.recover(); }
  /// Purges finished jobs past their retention time and collects unreferenced blobs (see Collector::sweep).
  SweepReport sweep() { return collector_.sweep(); }
  /// Answers every lease request held for work with "no work", and later ones at once (at shutdown, so that the
  /// transport's in-flight requests end).
  void stop_holding_leases() { lease_waiters_->close(); }

 private:
  std::optional<HttpResponse> check_access(const Route& route, const http::request_header<>& header);
  /// Routes, checks and hands the request to its resource handler; `send` gets the answer once (maybe later).
  void answer(HttpRequest&& request, std::function<void(HttpResponse)> send) noexcept;
  /// The answer to a refused request: 400, the ApiError's status, or 500 (logged).
  HttpResponse refusal(std::exception_ptr error, const HttpRequest& request) const;
  ResourceHandler& handler_for(RouteId route);

  Metrics& metrics_;
  ApiOptions opt_;
  TokenCheck token_check_;  // opt_.tokens' digests
  Scheduler& sched_;                              // notes new work to lease_waiters_ while this lives
  std::unique_ptr<LeaseWaiters> lease_waiters_;  // ended first in ~Api, while what its requests answer through lives
  JobService jobs_;
  Collector collector_;
  JobsHandler jobs_handler_;
  TilesHandler tiles_handler_;
  LeasesHandler leases_handler_;
  WorkersHandler workers_handler_;
  BlobsHandler blobs_handler_;
  HealthHandler health_handler_;
  EventsHandler events_handler_;
};

}  // namespace tessera::server
