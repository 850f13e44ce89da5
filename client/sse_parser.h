// Server-Sent Events as a client reads them: bytes in (split anywhere), whole events out. Comments and fields other
// than id, event and data are skipped; several data lines join with "\n". As in the SSE standard, an id holds for the
// events after it until another id comes.
#pragma once

#include <functional>
#include <string>
#include <string_view>

namespace tessera::client {

/// One received event.
struct SseMessage {
  std::string id;     ///< The latest "id:" field ("" before the first).
  std::string event;  ///< "event:" field ("message" when absent, as in the SSE standard).
  std::string data;   ///< The data lines.
};

/// Splits a byte stream into events.
class SseParser {
 public:
  /// Calls `on_event` for every complete event; its return value false stops feed() early (feed then returns false).
  explicit SseParser(std::function<bool(const SseMessage&)> on_event) : on_event_(std::move(on_event)) {}
  /// Consumes bytes; false when on_event asked to stop.
  bool feed(std::string_view bytes);

 private:
  bool line(std::string_view text);
  std::function<bool(const SseMessage&)> on_event_;
  std::string pending_;  // an incomplete line
  SseMessage current_;
  bool has_data_ = false;
};

}  // namespace tessera::client
