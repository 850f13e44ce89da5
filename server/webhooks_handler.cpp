#include "server/webhooks_handler.h"

namespace tessera::server {

namespace {
constexpr size_t kListed = 500;  // the most recent deliveries listed
}  // namespace

HttpResponse WebhooksHandler::handle(const protocol::RouteMatch&, HttpRequest& req, const Caller&) {
  protocol::WebhookDeliveryList list;
  if (log_) list.deliveries = log_->deliveries(kListed);
  return json_response(http::status::ok, list, req.version());
}

}  // namespace tessera::server
