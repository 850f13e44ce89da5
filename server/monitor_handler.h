// The web monitor in front of the API: serves the embedded static files at / and /monitor/..., tells the page which
// API endpoints this coordinator has, and hands every other request to the API unchanged.
#pragma once

#include "server/route.h"

#include <optional>

namespace tessera::server {

/// A RoutedHandler that serves the monitor's routes and hands every other request, with its route, to `api`.
class MonitorHandler final : public RoutedHandler {
 public:
  /// `api` answers every request that is not the monitor's; `tokens_required` is reported to the page so it asks for
  /// the client token before its first call.
  MonitorHandler(RoutedHandler& api, bool tokens_required);
  bool authenticated(const http::request_header<>& header) noexcept override { return api_.authenticated(header); }
  std::size_t routed_body_limit(const http::request_header<>& header, const Route& route) override;
  std::optional<HttpResponse> routed_early_response(const http::request_header<>& header, const Route& route) noexcept override;
  /// The monitor's files at once; the API's answers (streamed, or given later) pass through.
  void handle_routed(HttpRequest&& request, const Route& route, Reply done) noexcept override;

 private:
  HttpResponse serve(const HttpRequest& req) const;
  HttpResponse serve_static(const HttpRequest& req) const;
  HttpResponse capabilities(const HttpRequest& req) const;

  RoutedHandler& api_;
  bool tokens_required_;
};

}  // namespace tessera::server
