#include "protocol/json_fields.h"

#include "core/scene/json_depth.h"


#include <algorithm>
#include <limits>

namespace tessera::protocol {

using nlohmann::json;

json parse_body(const std::string& body, const std::string& what) {
  json j = json::parse(body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) throw ProtocolError(what + ": the coordinator's answer is not JSON");
  return j;
}

json parse_request_object(const std::string& body, std::initializer_list<const char*> known, bool allow_empty) {
  if (body.find_first_not_of(" \t\r\n") == std::string::npos) {
    if (allow_empty) return json::object();
    throw ProtocolError("request body is empty; expected a JSON object");
  }
  // Deep nesting is refused before parsing: printing, copying or destroying such a value recurses per level.
  if (json_nesting_depth(body) > kMaxSceneJsonDepth)
    throw ProtocolError("malformed JSON: arrays/objects nested deeper than " + std::to_string(kMaxSceneJsonDepth) +
                        " levels");
  json j;
  try {
    j = json::parse(body);
  } catch (const json::exception& e) {  // syntax errors, and numbers beyond the double range (out_of_range)
    throw ProtocolError(std::string("malformed JSON: ") + e.what());
  }
  if (!j.is_object()) throw ProtocolError(std::string("expected a JSON object, got ") + j.type_name());
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (std::none_of(known.begin(), known.end(), [&](const char* k) { return it.key() == k; })) {
      std::string list;
      for (const char* k : known) list += (list.empty() ? "" : ", ") + std::string(k);
      throw ProtocolError("unknown key '" + it.key() + "' (known keys: " + list + ")");
    }
  }
  return j;
}

int64_t request_int(const json& j, const char* key, int64_t fallback, int64_t lo, int64_t hi) {
  if (!j.contains(key)) return fallback;
  const json& v = j[key];
  if (!v.is_number_integer() ||
      (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t(std::numeric_limits<int64_t>::max())) ||
      v.get<int64_t>() < lo || v.get<int64_t>() > hi)
    throw ProtocolError(std::string("'") + key + "' must be an integer in " + std::to_string(lo) + ".." +
                        std::to_string(hi) + " (got " + v.dump() + ")");
  return v.get<int64_t>();
}

uint64_t request_uint(const json& j, const char* key, uint64_t fallback) {
  if (!j.contains(key)) return fallback;
  const json& v = j[key];
  if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0))
    throw ProtocolError(std::string("'") + key + "' must be a non-negative integer (got " + v.dump() + ")");
  return v.get<uint64_t>();
}

std::string request_string(const json& j, const char* key, const std::string& fallback) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_string())
    throw ProtocolError(std::string("'") + key + "' must be a string (got " + j[key].dump() + ")");
  return j[key].get<std::string>();
}

std::string bounded_text(std::string text, size_t max_bytes) {
  if (text.size() <= max_bytes) return text;
  const size_t original = text.size();
  size_t cut = max_bytes;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;  // not inside a UTF-8 character
  text.resize(cut);
  return text + " [cut from " + std::to_string(original) + " bytes]";
}

std::string request_bounded_string(const json& j, const char* key, const std::string& fallback, size_t max_bytes) {
  return bounded_text(request_string(j, key, fallback), max_bytes);
}

std::optional<std::vector<std::string>> request_strings(const json& j, const char* key, size_t max_count) {
  if (!j.contains(key)) return std::nullopt;
  const json& list = j[key];
  if (!list.is_array()) throw ProtocolError(std::string("\"") + key + "\" must be an array of strings");
  if (list.size() > max_count)
    throw ProtocolError(std::string("\"") + key + "\" lists " + std::to_string(list.size()) + " entries; at most " +
                        std::to_string(max_count) + " are allowed");
  std::vector<std::string> out;
  for (size_t i = 0; i < list.size(); ++i) {
    if (!list[i].is_string())
      throw ProtocolError(std::string("\"") + key + "\"[" + std::to_string(i) + "] must be a string");
    out.push_back(list[i].get<std::string>());
  }
  return out;
}

}  // namespace tessera::protocol
