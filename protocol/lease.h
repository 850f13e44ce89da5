// Where a lease is in its life (docs/protocol.md, "Jobs, tiles and leases"), as the coordinator stores it.
#pragma once

#include "core/util/enum_names.h"

#include <string_view>

namespace tessera::protocol {

/// Where a lease is: live until it expires, is revoked (cancel, re-lease), completes, is released or fails.
enum class LeaseState { live, expired, revoked, completed, released, failed };
/// The lowercase name of each lease state (as stored), in declaration order.
inline constexpr std::string_view kLeaseStateNames[] = {"live",      "expired",  "revoked",
                                                        "completed", "released", "failed"};

/// The lowercase name of a lease state (as stored).
inline const char* to_string(LeaseState s) { return enum_c_name(s, kLeaseStateNames); }
/// Parses a lease state name; throws std::invalid_argument for unknown names.
inline LeaseState lease_state_from_string(std::string_view s) {
  return enum_from_name_or_throw<LeaseState>(s, kLeaseStateNames, "lease state");
}

}  // namespace tessera::protocol
