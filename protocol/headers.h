// The HTTP header names the farm protocol adds to its requests and answers (docs/protocol.md).
#pragma once

namespace tessera::protocol {

/// Header of a tile result upload (PUT /v1/leases/{lease}/result): rays traced for the tile since the last heartbeat.
inline constexpr const char* kRaysHeader = "X-Tessera-Rays";
/// Header of the answer to a lease request that was held for work: how long it was held, in milliseconds.
inline constexpr const char* kHeldMsHeader = "X-Tessera-Held-Ms";

}  // namespace tessera::protocol
