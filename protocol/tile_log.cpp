#include "protocol/tile_log.h"

#include "protocol/errors.h"

#include <nlohmann/json.hpp>

namespace tessera::protocol {

using nlohmann::json;

namespace {

// The first `max` bytes of `line`, without a UTF-8 character cut in two.
std::string cut(const std::string& line, size_t max) {
  if (line.size() <= max) return line;
  size_t n = max;
  while (n > 0 && (static_cast<unsigned char>(line[n]) & 0xC0) == 0x80) --n;
  return line.substr(0, n);
}

std::string ascii_json(const json& j) { return j.dump(-1, ' ', true, json::error_handler_t::replace); }

}  // namespace

std::string tile_log_header(const std::vector<std::string>& lines) {
  const size_t first = lines.size() > kMaxTileLogLines ? lines.size() - kMaxTileLogLines : 0;
  json arr = json::array();
  for (size_t i = first; i < lines.size(); ++i) arr.push_back(cut(lines[i], kMaxTileLogLineBytes));
  std::string text = ascii_json(arr);
  while (text.size() > kMaxTileLogHeaderBytes && !arr.empty()) {
    arr.erase(arr.begin());
    text = ascii_json(arr);
  }
  return arr.empty() ? std::string() : text;
}

std::vector<std::string> parse_tile_log_header(std::string_view value) {
  const std::string name = kTileLogHeader;
  if (value.empty()) return {};
  if (value.size() > kMaxTileLogHeaderBytes)
    throw ProtocolError(name + " is " + std::to_string(value.size()) + " bytes, more than the limit of " +
                        std::to_string(kMaxTileLogHeaderBytes));
  json j;
  try {
    j = json::parse(value);
  } catch (const json::exception&) {
    throw ProtocolError(name + " must be a JSON array of strings");
  }
  if (!j.is_array() || j.size() > kMaxTileLogLines)
    throw ProtocolError(name + " must be a JSON array of at most " + std::to_string(kMaxTileLogLines) + " strings");
  std::vector<std::string> lines;
  lines.reserve(j.size());
  for (const json& line : j) {
    if (!line.is_string() || line.get_ref<const std::string&>().size() > kMaxTileLogLineBytes)
      throw ProtocolError(name + " lines must be strings of at most " + std::to_string(kMaxTileLogLineBytes) + " bytes");
    lines.push_back(line.get<std::string>());
  }
  return lines;
}

}  // namespace tessera::protocol
