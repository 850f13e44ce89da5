// Workers: registration, the list and drain/undrain.
#pragma once

#include "server/farm_events.h"
#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// POST and GET /v1/workers, POST /v1/workers/{wid}/drain and /undrain.
class WorkersHandler final : public ResourceHandler {
 public:
  /// Registers and controls workers with `scheduler` (which must outlive it), announces this heartbeat period and
  /// publishes registrations to `events`.
  WorkersHandler(Scheduler& scheduler, int heartbeat_seconds, FarmEvents& events)
      : sched_(scheduler), heartbeat_seconds_(heartbeat_seconds), events_(events) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req) override;

 private:
  Scheduler& sched_;
  int heartbeat_seconds_;
  FarmEvents& events_;
};

}  // namespace tessera::server
