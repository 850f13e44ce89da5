#include "protocol/access.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

#include <stdexcept>

namespace tessera::protocol {

Role role_from_string(std::string_view s) {
  if (const std::optional<Role> r = enum_from_name<Role>(s, kRoleNames)) return *r;
  throw std::invalid_argument("unknown role '" + std::string(s) + "' (roles: admin, user, viewer, worker)");
}

bool role_allows(Role role, Access access) {
  switch (access) {
    case Access::open: return true;
    case Access::either: return true;
    case Access::read: return role != Role::worker;
    case Access::submit:
    case Access::owner: return role == Role::admin || role == Role::user;
    case Access::admin: return role == Role::admin;
    case Access::worker: return role == Role::worker;
  }
  return false;
}

std::string roles_admitted(Access access) {
  switch (access) {
    case Access::open: return "no credential";
    case Access::either: return "any role";
    case Access::read: return "the viewer, user or admin role";
    case Access::submit: return "the user or admin role";
    case Access::owner: return "the user role (on its own jobs) or the admin role";
    case Access::admin: return "the admin role";
    case Access::worker: return "the worker role";
  }
  return "an unknown role";
}

void to_json(nlohmann::json& j, const Me& m) { j = {{"user", m.user}, {"role", to_string(m.role)}, {"controls", m.controls}}; }

void from_json(const nlohmann::json& j, Me& m) {
  m.user = answer_field<std::string>(j, "user", "me");
  try {
    m.role = role_from_string(answer_field<std::string>(j, "role", "me"));
  } catch (const std::invalid_argument& e) {
    throw ProtocolError(std::string("me: ") + e.what());
  }
  m.controls = answer_field_or<std::map<std::string, std::string>>(j, "controls", "me", {});
}

Me me_for(const std::string& user, Role role) {
  Me m{user, role, {}};
  for (const RouteSpec& r : route_table())
    for (const MethodSpec& method : r.methods) {
      if (method.capability.empty()) continue;
      const char* scope = !role_allows(role, method.access)                                   ? "none"
                          : method.access == Access::owner && !acts_on_any_job(role) ? "own"
                                                                                              : "any";
      m.controls[std::string(method.capability)] = scope;
    }
  return m;
}

}  // namespace tessera::protocol
