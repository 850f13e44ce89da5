// A request's route, decided once from its method and target by the first handler that sees it and handed on to the
// ones behind it: the protocol's route and method (with the token it needs and whether it waits for admission), or
// the web monitor's files.
#pragma once

#include "protocol/routes.h"
#include "server/http_server.h"

#include <cstddef>
#include <optional>
#include <string_view>

namespace tessera::server {

/// Where a request goes.
struct Route {
  protocol::RouteMatch match;                    ///< The protocol's route (match.route nullptr: none, a 404).
  const protocol::MethodSpec* method = nullptr;  ///< The route's entry for the request's method (nullptr: 404 or 405).
  bool monitor = false;                          ///< A web monitor path ("/" or "/monitor/..."), none of the API's.

  /// True when the request waits for its turn in the submission queue (server/admission_handler.h).
  bool admission() const { return method && method->admission; }
};

/// The monitor's path prefix: "/" and everything under it are the monitor's files.
inline constexpr std::string_view kMonitorPrefix = "/monitor/";

/// Routes a request by its header.
Route route_of(const http::request_header<>& header);

/// An HttpHandler that takes the route decided by the handler in front of it; as a plain HttpHandler it routes the
/// request itself first.
class RoutedHandler : public HttpHandler {
 public:
  /// body_limit() of a routed request.
  virtual std::size_t routed_body_limit(const http::request_header<>& header, const Route& route) = 0;
  /// early_response() of a routed request.
  virtual std::optional<HttpResponse> routed_early_response(const http::request_header<>& header,
                                                            const Route& route) noexcept = 0;
  /// handle_async() of a routed request.
  virtual void handle_routed(HttpRequest&& request, const Route& route, Reply done) noexcept = 0;

  std::size_t body_limit(const http::request_header<>& header) override;
  std::optional<HttpResponse> early_response(const http::request_header<>& header) noexcept override;
  /// reply()'s response (a stream's header only).
  HttpResponse handle(HttpRequest&& request) noexcept override;
  /// handle_routed(), waited for.
  HttpReply reply(HttpRequest&& request) noexcept override;
  void handle_async(HttpRequest&& request, Reply done) noexcept override;
};

}  // namespace tessera::server
