#include "server/tiles_handler.h"

namespace tessera::server {

using protocol::Endpoint;

HttpResponse TilesHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  const Endpoint endpoint = route.endpoint();
  const std::string& id = route.param;
  const unsigned v = req.version();
  switch (endpoint) {
    case Endpoint::job_tiles: return json_response(http::status::ok, jobs_.tiles(id), v);
    case Endpoint::job_tile_requeue:
      protocol::parse_empty_request(req.body());
      return json_response(http::status::ok, jobs_.requeue_tile(id, route.param2), v);
    default: break;
  }
  throw protocol::ApiError(404, "no such endpoint");
}

}  // namespace tessera::server
