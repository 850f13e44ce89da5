// What operators and their tools watch: liveness and Prometheus metrics.
#pragma once

#include "server/coordinator_store.h"
#include "server/disk_space.h"
#include "server/lease_waiters.h"
#include "server/metrics.h"
#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// GET /healthz (with the data folder's free space) and GET /metrics (with the store's disk costs).
class HealthHandler final : public ResourceHandler {
 public:
  /// Endpoints over the given state (which must outlive it).
  HealthHandler(Scheduler& scheduler, Metrics& metrics, ClockMs clock, LeaseWaiters& waiters, const DiskSpace& disk,
                const CoordinatorStore& store)
      : sched_(scheduler), metrics_(metrics), clock_(std::move(clock)), waiters_(waiters), disk_(disk), store_(store) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  Scheduler& sched_;
  Metrics& metrics_;
  ClockMs clock_;
  LeaseWaiters& waiters_;
  const DiskSpace& disk_;
  const CoordinatorStore& store_;
};

}  // namespace tessera::server
