// The protocol's defaults, in one place: what a job, a worker or a lease gets when a value is not given.
#pragma once

#include "core/sampling/adaptive.h"

#include <cstddef>
#include <cstdint>

namespace tessera::protocol {

inline constexpr int kDefaultTileSize = 64;                     ///< Tile edge of a job, pixels.
inline constexpr int kDefaultPriority = 0;                      ///< Job priority (higher runs first).
inline constexpr int64_t kDefaultTileTimeoutSeconds = 3600;     ///< A lease older than this is revoked (a failure).
inline constexpr int64_t kMaxTileTimeoutSeconds = 30 * 86400;   ///< The longest tile timeout a job may ask for.
inline constexpr size_t kMaxNameBytes = 256;  ///< The longest job or worker name stored; longer ones are cut and marked.
inline constexpr uint32_t kDefaultMinSpp = kAdaptiveMinSpp;     ///< Adaptive sampling: first round.
inline constexpr uint32_t kDefaultMaxSpp = kAdaptiveMaxSpp;     ///< Adaptive sampling: most samples per pixel.
inline constexpr double kDefaultLeaseSeconds = 30;              ///< Lease length.
inline constexpr int kDefaultHeartbeatSeconds = 5;              ///< Heartbeat period announced to workers.

}  // namespace tessera::protocol
