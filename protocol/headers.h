// The HTTP header names the farm protocol adds to its requests and answers (docs/protocol.md).
#pragma once

namespace tessera::protocol {

/// Header of a tile result upload (PUT /v1/leases/{lease}/result): rays traced for the tile since the last heartbeat.
inline constexpr const char* kRaysHeader = "X-Tessera-Rays";
/// Header of a tile result upload that also asks for the worker's next lease: the JSON of a lease request
/// (protocol::LeaseRequest, as POST /v1/workers/{wid}/lease takes it, without wait_ms), written in ASCII. The answer
/// carries that lease under "next" when the upload is settled accepted or duplicate and a tile is leasable by the
/// worker (docs/protocol.md, "One request per tile"). Absent: the upload asks for nothing more.
inline constexpr const char* kNextLeaseHeader = "X-Tessera-Next-Lease";
/// Header of the answer to a lease request that was held for work: how long it was held, in milliseconds.
inline constexpr const char* kHeldMsHeader = "X-Tessera-Held-Ms";
/// Header of every request that acts as a registered worker (its lease requests, and the heartbeats, result uploads,
/// failure reports, releases and state downloads of its leases): the secret its registration returned.
inline constexpr const char* kWorkerSecretHeader = "X-Tessera-Worker-Secret";

}  // namespace tessera::protocol
