// Where the audit trail is kept (GET /v1/audit): one row per control action, kept as long as finished jobs are.
#pragma once

#include "protocol/audit.h"
#include "protocol/query.h"

#include <cstdint>

namespace tessera::server {

/// The audit trail's storage.
class AuditStore {
 public:
  virtual ~AuditStore() = default;
  /// Appends an entry (its id is assigned here, increasing); throws StorageError.
  virtual void append_audit(const protocol::AuditEntry& entry) = 0;
  /// A page of entries, newest first, as the query asks; throws StorageError.
  virtual protocol::AuditList audit(const protocol::AuditQuery& query) = 0;
  /// Forgets entries older than `before_ms`; returns how many; throws StorageError.
  virtual int64_t forget_audit(int64_t before_ms) = 0;
};

}  // namespace tessera::server
