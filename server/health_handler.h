// What operators and their tools watch: liveness and Prometheus metrics.
#pragma once

#include "server/metrics.h"
#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// GET /healthz and GET /metrics.
class HealthHandler final : public ResourceHandler {
 public:
  /// Endpoints over the given state (which must outlive it).
  HealthHandler(Scheduler& scheduler, Metrics& metrics, ClockMs clock)
      : sched_(scheduler), metrics_(metrics), clock_(std::move(clock)) {}
  HttpResponse handle(protocol::Endpoint endpoint, const std::string& param, HttpRequest& req) override;

 private:
  Scheduler& sched_;
  Metrics& metrics_;
  ClockMs clock_;
};

}  // namespace tessera::server
