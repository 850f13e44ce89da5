#include "protocol/audit.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const AuditEntry& e) {
  j = {{"id", e.id},         {"at_ms", e.at_ms},   {"user", e.user},       {"role", e.role},
       {"action", e.action}, {"target", e.target}, {"address", e.address}, {"status", e.status}};
}

void from_json(const json& j, AuditEntry& e) {
  constexpr const char* kMsg = "audit entry";
  e.id = answer_field<int64_t>(j, "id", kMsg);
  e.at_ms = answer_field<int64_t>(j, "at_ms", kMsg);
  e.user = answer_field<std::string>(j, "user", kMsg);
  e.role = answer_field_or<std::string>(j, "role", kMsg, "");
  e.action = answer_field<std::string>(j, "action", kMsg);
  e.target = answer_field_or<std::string>(j, "target", kMsg, "");
  e.address = answer_field_or<std::string>(j, "address", kMsg, "");
  e.status = answer_field_or<int>(j, "status", kMsg, 0);
}

void to_json(json& j, const AuditList& l) { j = {{"entries", l.entries}, {"next", optional_json(l.next)}}; }

void from_json(const json& j, AuditList& l) {
  l.entries = answer_field<std::vector<AuditEntry>>(j, "entries", "audit list");
  l.next.reset();
  if (j.contains("next") && !j["next"].is_null()) l.next = answer_field<int64_t>(j, "next", "audit list");
}

}  // namespace tessera::protocol
