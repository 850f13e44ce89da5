#include "server/health_handler.h"

namespace tessera::server {

HttpResponse HealthHandler::handle(const protocol::RouteMatch& route, HttpRequest& req) {
  if (route.endpoint() == protocol::Endpoint::healthz) return json_response(http::status::ok, protocol::HealthAnswer{}, req.version());
  return bytes_response(metrics_.prometheus(sched_.counters(), clock_(), waiters_.held()), "text/plain; version=0.0.4", req.version());
}

}  // namespace tessera::server
