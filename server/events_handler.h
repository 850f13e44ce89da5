// GET /v1/events: the event bus as Server-Sent Events (text/event-stream), one subscription per stream.
#pragma once

#include "server/event_bus.h"
#include "server/http_server.h"

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace tessera::server {

/// Opens event streams over a bus.
class EventsHandler {
 public:
  /// Streams from `bus` (which must outlive every stream it opens).
  explicit EventsHandler(EventBus& bus) : bus_(bus) {}
  /// A streamed answer subscribed to the bus for a caller who showed `credential` (server/auth.h), resuming after
  /// the request's Last-Event-ID when it has one; 503 (as an ordinary answer) when the bus takes no more subscribers.
  HttpReply open(const HttpRequest& request, const std::string& credential);
  /// Ends every open stream whose credential `admitted` no longer accepts (a user removed from the users file);
  /// returns how many it ended.
  size_t end_unless(const std::function<bool(const std::string& credential)>& admitted);

 private:
  EventBus& bus_;
  std::mutex mu_;
  std::vector<std::pair<std::string, std::weak_ptr<Subscription>>> open_;  // (mu_) credential, subscription
};

/// The SSE text of one event: "id:", "event:" and "data:" lines and a blank line.
std::string sse_message(const Event& event);

}  // namespace tessera::server
