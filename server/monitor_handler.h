// The web monitor in front of the API: serves the embedded static files at / and /monitor/..., tells the page which
// API endpoints this coordinator has, and hands every other request to the API unchanged.
#pragma once

#include "server/http_server.h"

#include <optional>

namespace tessera::server {

/// An HttpHandler that serves the monitor and forwards everything else to `api`.
class MonitorHandler final : public HttpHandler {
 public:
  /// `api` answers every request that is not the monitor's; `tokens_required` is reported to the page so it asks for
  /// the client token before its first call.
  MonitorHandler(HttpHandler& api, bool tokens_required);
  std::size_t body_limit(const http::request_header<>& header) override;
  std::optional<HttpResponse> early_response(const http::request_header<>& header) noexcept override;
  HttpResponse handle(HttpRequest&& request) noexcept override;
  /// The API's streamed answers (GET /v1/events) pass through; everything else is handle().
  HttpReply reply(HttpRequest&& request) noexcept override;
  /// As reply(), passing on the API's answers given later (result uploads).
  void handle_async(HttpRequest&& request, Reply done) noexcept override;

 private:
  HttpResponse serve_static(const HttpRequest& req) const;
  HttpResponse capabilities(const HttpRequest& req) const;

  HttpHandler& api_;
  bool tokens_required_;
};

}  // namespace tessera::server
