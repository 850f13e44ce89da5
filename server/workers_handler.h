// Workers: registration, the list and drain/undrain.
#pragma once

#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// POST and GET /v1/workers, POST /v1/workers/{wid}/drain and /undrain.
class WorkersHandler final : public ResourceHandler {
 public:
  /// Registers and controls workers with `scheduler` (which must outlive it) and announces this heartbeat period.
  WorkersHandler(Scheduler& scheduler, int heartbeat_seconds) : sched_(scheduler), heartbeat_seconds_(heartbeat_seconds) {}
  HttpResponse handle(protocol::Endpoint endpoint, const std::string& id, HttpRequest& req) override;

 private:
  Scheduler& sched_;
  int heartbeat_seconds_;
};

}  // namespace tessera::server
