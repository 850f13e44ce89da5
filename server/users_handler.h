// GET /v1/me (who the coordinator takes the caller for, and what the monitor may offer it) and GET /v1/audit (the
// audit trail, for admins).
#pragma once

#include "server/audit_trail.h"
#include "server/resource_handler.h"

namespace tessera::server {

/// Answers the users resource.
class UsersHandler final : public ResourceHandler {
 public:
  /// Lists `trail` (which must outlive it).
  explicit UsersHandler(AuditTrail& trail) : trail_(trail) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  AuditTrail& trail_;
};

}  // namespace tessera::server
