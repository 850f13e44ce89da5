#include "server/health_handler.h"

namespace tessera::server {

HttpResponse HealthHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  if (route.endpoint() == protocol::Endpoint::healthz) {
    // 200 whatever the disk: the coordinator still serves, and restarting it would not free any space.
    protocol::HealthAnswer a;
    a.disk = disk_.state();
    if (a.disk != protocol::DiskState::ok) a.status = "degraded";
    a.disk_free_bytes = disk_.free_bytes();
    a.min_free_disk = disk_.min_free();
    return json_response(http::status::ok, a, req.version());
  }
  return bytes_response(metrics_.prometheus(sched_.counters(), clock_(), waiters_.held(), store_.stats()),
                        "text/plain; version=0.0.4", req.version());
}

}  // namespace tessera::server
