// Worker endpoints of tiles: ask for a lease, heartbeat it, upload its result, report a failure, hand it back.
#pragma once

#include "server/farm_events.h"
#include "server/job_service.h"
#include "server/metrics.h"
#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// /v1/workers/{wid}/lease and /v1/leases/{lease}/heartbeat, /result, /fail, /release.
class LeasesHandler final : public ResourceHandler {
 public:
  /// Endpoints over the given state (which must outlive it).
  /// Publishes each lease granted (and its job's start) to `events`.
  LeasesHandler(Scheduler& scheduler, JobService& jobs, Metrics& metrics, ClockMs clock, FarmEvents& events)
      : sched_(scheduler), jobs_(jobs), metrics_(metrics), clock_(std::move(clock)), events_(events) {}
  HttpResponse handle(protocol::Endpoint endpoint, const std::string& id, HttpRequest& req) override;
  /// Result uploads are answered once their tile is durable (JobService::accept_tile); the rest as handle().
  void handle_async(protocol::Endpoint endpoint, const std::string& id, HttpRequest& req, Answer answer) override;

 private:
  HttpResponse lease(const std::string& worker, HttpRequest& req);
  HttpResponse heartbeat(const std::string& lease, HttpRequest& req);
  void result(const std::string& lease, HttpRequest& req, Answer answer);

  Scheduler& sched_;
  JobService& jobs_;
  Metrics& metrics_;
  ClockMs clock_;
  FarmEvents& events_;
};

}  // namespace tessera::server
