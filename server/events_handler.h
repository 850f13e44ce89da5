// GET /v1/events: the event bus as Server-Sent Events (text/event-stream), one subscription per stream.
#pragma once

#include "server/event_bus.h"
#include "server/http_server.h"

namespace tessera::server {

/// Opens event streams over a bus.
class EventsHandler {
 public:
  /// Streams from `bus` (which must outlive every stream it opens).
  explicit EventsHandler(EventBus& bus) : bus_(bus) {}
  /// A streamed answer subscribed to the bus, resuming after the request's Last-Event-ID when it has one; 503 (as
  /// an ordinary answer) when the bus takes no more subscribers.
  HttpReply open(const HttpRequest& request);

 private:
  EventBus& bus_;
};

/// The SSE text of one event: "id:", "event:" and "data:" lines and a blank line.
std::string sse_message(const Event& event);

}  // namespace tessera::server
