// The audit trail's rules (docs/operations.md, "Running a shared farm"): which requests it records (submissions and
// every control of a job, a worker or the farm, answered or refused), what an entry holds, and how long it is kept
// (as long as finished jobs: `serve --retain-finished`).
#pragma once

#include "protocol/routes.h"
#include "server/audit_store.h"
#include "server/auth.h"
#include "server/scheduler_types.h"

#include <cstdint>
#include <optional>
#include <string>

namespace tessera::server {

/// Records control actions in an AuditStore and lists them. Thread-safe as the store is.
class AuditTrail {
 public:
  /// A trail in `store` (which must outlive it) stamped by `clock`, forgetting entries older than `retain_ms` on
  /// sweep() (none: kept forever).
  AuditTrail(AuditStore& store, ClockMs clock, std::optional<int64_t> retain_ms)
      : store_(store), clock_(std::move(clock)), retain_ms_(retain_ms) {}

  /// True for the methods the trail records: submissions, and every method a job's owner or an admin may call that
  /// changes something.
  static bool records(const protocol::RouteSpec& route, const protocol::MethodSpec& method);
  /// Records that `caller` at `address` called `method` on `route` for `target` and was answered `status`; a store
  /// failure is logged, never thrown (the action stands).
  void record(const Caller& caller, const protocol::RouteSpec& route, const protocol::MethodSpec& method,
              const std::string& target, const std::string& address, int status) noexcept;
  /// A page of entries, newest first.
  protocol::AuditList list(const protocol::AuditQuery& query) { return store_.audit(query); }
  /// Forgets entries past the retention time; returns how many.
  int64_t sweep();

 private:
  AuditStore& store_;
  ClockMs clock_;
  std::optional<int64_t> retain_ms_;
};

}  // namespace tessera::server
