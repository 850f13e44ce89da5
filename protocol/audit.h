// The audit trail (GET /v1/audit): every control action taken on the farm, who took it, when and from where.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tessera::protocol {

/// One action as the audit trail records it.
struct AuditEntry {
  int64_t id = 0;        ///< Increasing number (the listing's cursor).
  int64_t at_ms = 0;     ///< When it was answered (Unix ms).
  std::string user;      ///< Who took it.
  std::string role;      ///< The role it was taken with.
  std::string action;    ///< Method and route, e.g. "POST /v1/jobs/{id}/pause".
  std::string target;    ///< The job or worker it acted on ("" for a submission before it had an id).
  std::string address;   ///< The caller's network address.
  int status = 0;        ///< The HTTP status answered.
};
void to_json(nlohmann::json& j, const AuditEntry& e);
void from_json(const nlohmann::json& j, AuditEntry& e);

/// Answer of GET /v1/audit: entries newest first.
struct AuditList {
  std::vector<AuditEntry> entries;  ///< Newest first.
  std::optional<int64_t> next;      ///< The `before` of the next (older) page; null on the last page.
};
void to_json(nlohmann::json& j, const AuditList& l);
void from_json(const nlohmann::json& j, AuditList& l);

}  // namespace tessera::protocol
