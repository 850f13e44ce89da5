// GET /v1/webhooks/deliveries: the webhook delivery log, most recent first, with each delivery's attempts and its last
// answer.
#pragma once

#include "server/resource_handler.h"
#include "server/webhook_log.h"

namespace tessera::server {

/// The webhooks resource.
class WebhooksHandler final : public ResourceHandler {
 public:
  /// Lists from `log` (nullptr: a coordinator that keeps none answers an empty list).
  explicit WebhooksHandler(WebhookLog* log) : log_(log) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  WebhookLog* log_;
};

}  // namespace tessera::server
