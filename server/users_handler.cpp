#include "server/users_handler.h"

#include "protocol/query.h"

namespace tessera::server {

HttpResponse UsersHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) {
  const unsigned v = req.version();
  if (route.endpoint() == protocol::Endpoint::me)
    return json_response(http::status::ok, protocol::me_for(caller.user, caller.role), v);
  return json_response(http::status::ok, trail_.list(protocol::parse_audit_query(req.target())), v);
}

}  // namespace tessera::server
