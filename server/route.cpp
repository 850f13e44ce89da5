#include "server/route.h"

#include <future>

namespace tessera::server {

Route route_of(const http::request_header<>& header) {
  Route r;
  const std::string_view target = header.target();
  const std::string_view path = target.substr(0, target.find('?'));
  if (path == "/" || path.starts_with(kMonitorPrefix)) {
    r.monitor = true;
    return r;
  }
  r.match = protocol::match_route(target);
  r.method = r.match.method(header.method_string());
  return r;
}

std::size_t RoutedHandler::body_limit(const http::request_header<>& header) {
  return routed_body_limit(header, route_of(header));
}

std::optional<HttpResponse> RoutedHandler::early_response(const http::request_header<>& header) noexcept {
  try {
    return routed_early_response(header, route_of(header));
  } catch (...) {
    return json_error(http::status::internal_server_error, "internal error", header.version());
  }
}

HttpResponse RoutedHandler::handle(HttpRequest&& request) noexcept { return reply(std::move(request)).response; }

HttpReply RoutedHandler::reply(HttpRequest&& request) noexcept {
  std::promise<HttpReply> promise;
  std::future<HttpReply> answered = promise.get_future();
  handle_async(std::move(request), [&promise](HttpReply r) { promise.set_value(std::move(r)); });
  return answered.get();
}

void RoutedHandler::handle_async(HttpRequest&& request, Reply done) noexcept {
  Route route;
  try {
    route = route_of(request);
  } catch (...) {
    return done({json_error(http::status::internal_server_error, "internal error", request.version()), nullptr});
  }
  handle_routed(std::move(request), route, std::move(done));
}

}  // namespace tessera::server
