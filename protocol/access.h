// Who may call what: the roles of a shared farm's users (docs/operations.md, "Running a shared farm"), the rule that
// decides which roles a method's access admits, and the caller's view of it (GET /v1/me).
#pragma once

#include "core/util/enum_names.h"
#include "protocol/routes.h"

#include <nlohmann/json_fwd.hpp>

#include <map>
#include <string>
#include <string_view>

namespace tessera::protocol {

/// admin: everything; user: submit, read, control its own jobs; viewer: read; worker: lease and upload.
enum class Role { admin, user, viewer, worker };
/// The protocol's name of each role, in declaration order.
inline constexpr std::string_view kRoleNames[] = {"admin", "user", "viewer", "worker"};
/// The name of a role.
inline const char* to_string(Role r) { return enum_c_name(r, kRoleNames); }
/// Parses a role name; throws std::invalid_argument naming the roles for an unknown one.
Role role_from_string(std::string_view s);

/// True when a caller in `role` may call a method needing `access` (Access::owner: on its own jobs, unless admin).
bool role_allows(Role role, Access access);
/// True when `role` may act on jobs of other users with Access::owner methods.
inline bool acts_on_any_job(Role role) { return role == Role::admin; }
/// The roles `access` admits, as a phrase for a refusal ("the admin role", "the user or admin role"...).
std::string roles_admitted(Access access);

/// Answer of GET /v1/me: who the coordinator takes the caller for, and what the monitor may offer it.
struct Me {
  std::string user;  ///< The caller's user name ("client" for the client token, "worker" for the worker token).
  Role role = Role::admin;  ///< Its role.
  /// Each monitor control (a route method's capability) -> "any" (every job), "own" (the caller's jobs) or "none".
  std::map<std::string, std::string> controls;
};
void to_json(nlohmann::json& j, const Me& m);
void from_json(const nlohmann::json& j, Me& m);
/// The answer for a caller with this name and role (controls from the route table).
Me me_for(const std::string& user, Role role);

}  // namespace tessera::protocol
