// Reading JSON messages field by field with errors that name the field: strict readers for requests (the coordinator
// refuses unknown keys and out-of-range values) and tolerant ones for answers (clients ignore keys they do not know).
#pragma once

#include "protocol/errors.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

namespace tessera::protocol {

/// Parses a message body as JSON; throws ProtocolError naming `what` on malformed text.
nlohmann::json parse_body(const std::string& body, const std::string& what);

/// Parses a request body that must be a JSON object and refuses keys outside `known` (an empty body is {} when
/// allowed); throws ProtocolError with the sentence the coordinator answers.
nlohmann::json parse_request_object(const std::string& body, std::initializer_list<const char*> known, bool allow_empty);

/// Request fields: `key`'s value or `fallback` when absent; throws ProtocolError naming the key and the allowed range.
int64_t request_int(const nlohmann::json& j, const char* key, int64_t fallback, int64_t lo, int64_t hi);
/// A non-negative integer request field.
uint64_t request_uint(const nlohmann::json& j, const char* key, uint64_t fallback);
/// A string request field.
std::string request_string(const nlohmann::json& j, const char* key, const std::string& fallback);
/// A string request field the coordinator stores: longer than `max_bytes`, it is cut (at a UTF-8 character boundary)
/// and marked as cut, " [cut from N bytes]", so a stored text never exceeds max_bytes plus that mark.
std::string request_bounded_string(const nlohmann::json& j, const char* key, const std::string& fallback,
                                   size_t max_bytes);
/// `text` as request_bounded_string stores it.
std::string bounded_text(std::string text, size_t max_bytes);
/// An array-of-strings request field of at most `max_count` entries; nothing when absent.
std::optional<std::vector<std::string>> request_strings(const nlohmann::json& j, const char* key, size_t max_count);

/// Answer fields: the field `key` of object j converted to T; throws ProtocolError naming the message and the field.
template <class T>
T answer_field(const nlohmann::json& j, const char* key, const char* message) {
  if (!j.is_object()) throw ProtocolError(std::string(message) + ": not a JSON object");
  const auto it = j.find(key);
  if (it == j.end()) throw ProtocolError(std::string(message) + ": missing \"" + key + "\"");
  try {
    return it->get<T>();
  } catch (const nlohmann::json::exception& e) {
    throw ProtocolError(std::string(message) + ": \"" + key + "\" has the wrong type (" + e.what() + ")");
  }
}

/// An optional value as JSON: its value, or null when empty.
template <class Optional>
nlohmann::json optional_json(const Optional& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

/// An optional answer field: `fallback` when absent or null.
template <class T>
T answer_field_or(const nlohmann::json& j, const char* key, const char* message, T fallback) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return fallback;
  return answer_field<T>(j, key, message);
}

/// An optional answer field that is a message of its own (its from_json throws ProtocolError): nothing when absent or
/// null; its error is prefixed with the message and the field.
template <class T>
std::optional<T> optional_message_field(const nlohmann::json& j, const char* key, const char* message) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return std::nullopt;
  try {
    return j[key].get<T>();
  } catch (const ProtocolError& e) {
    throw ProtocolError(std::string(message) + ": \"" + key + "\": " + e.what());
  }
}

}  // namespace tessera::protocol
