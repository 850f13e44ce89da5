#include "server/audit_trail.h"

#include <spdlog/spdlog.h>

namespace tessera::server {

bool AuditTrail::records(const protocol::RouteSpec& route, const protocol::MethodSpec& method) {
  using protocol::Access;
  if (route.endpoint == protocol::Endpoint::jobs) return method.name == "POST";
  return method.name != "GET" && method.name != "HEAD" && (method.access == Access::owner || method.access == Access::admin);
}

void AuditTrail::record(const Caller& caller, const protocol::RouteSpec& route, const protocol::MethodSpec& method,
                        const std::string& target, const std::string& address, int status) noexcept {
  try {
    protocol::AuditEntry e;
    e.at_ms = clock_();
    e.user = caller.user;
    e.role = protocol::to_string(caller.role);
    e.action = std::string(method.name) + " " + std::string(route.pattern);
    e.target = target;
    e.address = address;
    e.status = status;
    store_.append_audit(e);
  } catch (const std::exception& e) {
    spdlog::error("audit trail: {} {} by {} not recorded: {}", std::string(method.name), std::string(route.pattern),
                  caller.user, e.what());
  }
}

int64_t AuditTrail::sweep() {
  if (!retain_ms_) return 0;
  const int64_t n = store_.forget_audit(clock_() - *retain_ms_);
  if (n) spdlog::info("retention: forgot {} audit entries", n);
  return n;
}

}  // namespace tessera::server
