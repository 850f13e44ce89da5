// One resource's endpoints behind the router (server/api.h): requests arrive matched, authorised and within their
// size limit, with the caller their credential stands for; refusals are thrown as protocol::ApiError or
// protocol::ProtocolError.
#pragma once

#include "protocol/errors.h"
#include "protocol/routes.h"
#include "server/auth.h"
#include "server/http_server.h"

#include <nlohmann/json.hpp>

#include <exception>
#include <functional>
#include <optional>
#include <string>

namespace tessera::server {

/// Where an answer given later goes: called once, with the response or with the exception that refuses the request.
using Answer = std::function<void(HttpResponse response, std::exception_ptr refusal)>;

/// Handles the endpoints of one resource.
class ResourceHandler {
 public:
  virtual ~ResourceHandler() = default;
  /// Answers a request of `caller` for the matched `route` (one of this handler's endpoints, with its path
  /// parameters).
  virtual HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& request, const Caller& caller) = 0;
  /// As handle(), but the answer may come later, from another thread (the request is read only before this returns).
  /// By default handle() answers at once.
  virtual void handle_async(const protocol::RouteMatch& route, HttpRequest& request, const Caller& caller,
                            Answer answer);
  /// An answer whose body is streamed (a stored file), or nothing for handle_async() to answer instead. Throws
  /// refusals as handle() does.
  virtual std::optional<HttpReply> stream(const protocol::RouteMatch& /*route*/, HttpRequest& /*request*/,
                                          const Caller& /*caller*/) {
    return std::nullopt;
  }
};

/// A JSON answer.
HttpResponse json_response(http::status status, const nlohmann::json& body, unsigned version);
/// A 200 answer with these bytes.
HttpResponse bytes_response(std::string bytes, const char* content_type, unsigned version);

}  // namespace tessera::server
