#include "cli/audit_command.h"

#include "client/job_client.h"
#include "protocol/query.h"

#include <cstdio>
#include <ctime>

namespace tessera::cli {

CLI::App* add_audit_command(CLI::App& app, AuditArgs& a) {
  auto* c = app.add_subcommand("audit", "Show the coordinator's audit trail, newest first (admins only)");
  c->add_option("--user", a.user, "Only this user's actions");
  c->add_option("--limit", a.limit, "At most this many entries")->check(CLI::Range(size_t(1), protocol::kMaxJobListLimit))
      ->capture_default_str();
  c->add_option("--before", a.before, "Only entries numbered below this (printed by a listing that has more)")
      ->check(CLI::PositiveNumber);
  add_coordinator_access_flags(c, a.access);
  return c;
}

int run_audit(const AuditArgs& a) {
  return run_with_coordinator(a.access, "audit", [&](client::HttpClient& http) {
    protocol::AuditQuery q;
    q.limit = a.limit;
    q.user = a.user;
    if (a.before > 0) q.before = a.before;
    const protocol::AuditList page = client::list_audit(http, q);
    std::printf("%8s %-20s %-16s %-7s %-40s %-22s %6s  %s\n", "ID", "TIME (UTC)", "USER", "ROLE", "ACTION", "TARGET",
                "STATUS", "FROM");
    for (const protocol::AuditEntry& e : page.entries) {
      const std::time_t t = std::time_t(e.at_ms / 1000);
      std::tm tm{};
      gmtime_r(&t, &tm);
      char when[32];
      std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S", &tm);
      std::printf("%8lld %-20s %-16s %-7s %-40s %-22s %6d  %s\n", static_cast<long long>(e.id), when, e.user.c_str(),
                  e.role.c_str(), e.action.c_str(), e.target.empty() ? "-" : e.target.c_str(), e.status,
                  e.address.c_str());
    }
    if (page.next) std::printf("more: --before %lld\n", static_cast<long long>(*page.next));
    return 0;
  });
}

}  // namespace tessera::cli
