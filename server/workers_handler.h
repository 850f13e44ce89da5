// Workers: registration, the list and drain/undrain.
#pragma once

#include "server/farm_events.h"
#include "server/registration_limit.h"
#include "server/resource_handler.h"
#include "server/scheduler.h"

namespace tessera::server {

/// POST and GET /v1/workers, POST /v1/workers/{wid}/drain and /undrain.
class WorkersHandler final : public ResourceHandler {
 public:
  /// Registers and controls workers with `scheduler` (which must outlive it), announces this heartbeat period,
  /// takes at most `registrations_per_minute` registrations a minute by `clock` (0: no limit) and publishes
  /// registrations to `events`.
  WorkersHandler(Scheduler& scheduler, int heartbeat_seconds, double registrations_per_minute, ClockMs clock,
                 FarmEvents& events)
      : sched_(scheduler),
        heartbeat_seconds_(heartbeat_seconds),
        registrations_per_minute_(registrations_per_minute),
        registrations_(registrations_per_minute),
        clock_(std::move(clock)),
        events_(events) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  // POST /v1/workers: 201 with the new worker's id and secret, 429 past the rate, 503 past the bound.
  HttpResponse register_worker(HttpRequest& req);

  Scheduler& sched_;
  int heartbeat_seconds_;
  double registrations_per_minute_;
  RegistrationLimit registrations_;
  ClockMs clock_;
  FarmEvents& events_;
};

}  // namespace tessera::server
