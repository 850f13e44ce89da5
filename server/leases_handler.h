// Worker endpoints of tiles: ask for a lease, heartbeat it, upload its result, report a failure, hand it back.
#pragma once

#include "server/farm_events.h"
#include "server/job_service.h"
#include "server/lease_waiters.h"
#include "server/log_limit.h"
#include "server/metrics.h"
#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// /v1/workers/{wid}/lease and /v1/leases/{lease}/heartbeat, /result, /fail, /release, /state: each only for the
/// worker it names (its lease's worker), which proves who it is with its secret (protocol::kWorkerSecretHeader).
class LeasesHandler final : public ResourceHandler {
 public:
  /// Endpoints over the given state (which must outlive it).
  /// Publishes each lease granted (and its job's start) to `events`; lease requests that may wait are held in `waiters`.
  /// The next lease an upload asks for is granted through `background` (run inline when empty), off the thread that
  /// acknowledges durable uploads.
  LeasesHandler(Scheduler& scheduler, JobService& jobs, Metrics& metrics, ClockMs clock, FarmEvents& events,
                LeaseWaiters& waiters, Background background = {});
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;
  /// Result uploads are answered once their tile is durable (JobService::accept_tile), and with the next lease they
  /// ask for (protocol::kNextLeaseHeader) once it is granted; lease requests with a wait once there is a tile or the
  /// wait is over; the rest as handle().
  void handle_async(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller, Answer answer) override;

 private:
  void lease(const std::string& worker, HttpRequest& req, Answer answer);
  // A lease for the worker as the lease route's answer text, or nothing when there is no work for it; throws ApiError
  // (404) for an unknown worker. The one way a lease is granted, for a lease request and for an upload that asks.
  // With `leased_event`, the lease's tile_leased event is left there for the caller to publish.
  std::optional<std::string> try_lease(const std::string& worker, const protocol::LeaseRequest& asked,
                                       std::function<void()>* leased_event = nullptr);
  HttpResponse heartbeat(const std::string& lease, HttpRequest& req);
  // Throws ApiError unless the request carries the secret of the worker `worker` (404 unknown, 403 not its secret).
  void require_worker(const std::string& worker, const HttpRequest& req);
  // Throws ApiError unless the request carries the secret of the worker the lease was granted to (404 for an unknown
  // lease or a forgotten worker, 403 for any other worker's secret or none); sets `holder` to that worker.
  void require_holder(const std::string& lease, const HttpRequest& req, std::string* holder = nullptr);
  // Logs (a few lines a minute) and throws the 403 of a request that is not the worker's it claims to be.
  [[noreturn]] void refuse_identity(const std::string& why);
  void result(const std::string& lease, HttpRequest& req, Answer answer);

  Scheduler& sched_;
  JobService& jobs_;
  Metrics& metrics_;
  ClockMs clock_;
  FarmEvents& events_;
  LeaseWaiters& waiters_;
  Background background_;
  LogLimit refusal_log_{10, std::chrono::minutes(1)};  // the 403 lines of requests with another worker's secret
};

}  // namespace tessera::server
