#include "client/sse_parser.h"

namespace tessera::client {

bool SseParser::feed(std::string_view bytes) {
  pending_.append(bytes);
  size_t start = 0;
  for (;;) {
    const size_t nl = pending_.find('\n', start);
    if (nl == std::string::npos) break;
    std::string_view text(pending_.data() + start, nl - start);
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    start = nl + 1;
    if (!line(text)) {
      pending_.erase(0, start);
      return false;
    }
  }
  pending_.erase(0, start);
  return true;
}

bool SseParser::line(std::string_view text) {
  if (text.empty()) {  // the end of an event
    bool go_on = true;
    if (has_data_) {
      if (current_.event.empty()) current_.event = "message";
      go_on = on_event_(current_);
    }
    current_.event.clear();
    current_.data.clear();
    has_data_ = false;
    return go_on;
  }
  if (text.front() == ':') return true;  // a comment
  const size_t colon = text.find(':');
  const std::string_view field = text.substr(0, colon);
  std::string_view value = colon == std::string_view::npos ? std::string_view() : text.substr(colon + 1);
  if (!value.empty() && value.front() == ' ') value.remove_prefix(1);
  if (field == "id") current_.id = value;
  else if (field == "event") current_.event = value;
  else if (field == "data") {
    if (has_data_) current_.data += '\n';
    current_.data += value;
    has_data_ = true;
  }
  return true;
}

}  // namespace tessera::client
