// A finished tile's upload: its pixels encoded as an uncompressed EXR and PUT to its lease's result, retried until
// the coordinator settles it.
#pragma once

#include "client/http_client.h"
#include "core/render/render.h"
#include "protocol/messages.h"

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace tessera::worker {

/// How a tile's upload ended.
enum class DeliveryOutcome {
  kUploaded,  ///< The coordinator accepted the result (or acknowledged it as a duplicate).
  kDropped,   ///< The lease or job is gone, the answer cannot be retried, or the upload was abandoned.
  kFailed,    ///< The coordinator refused the result as invalid (422).
};

/// How a tile's upload ended, and the worker's next lease when the upload asked for one and its answer carried it.
struct Delivery {
  DeliveryOutcome outcome = DeliveryOutcome::kDropped;
  std::optional<protocol::LeaseAnswer> next;
};

/// Uploads the render of lease `l`'s tile of a width x height image through `http`, as the worker whose secret is
/// `worker_secret`, logging under `prefix`, with `log` (its last log lines about the lease, oldest first; cut to the
/// protocol's bounds, protocol/tile_log.h) for the coordinator to keep with the done tile; an upload answered 431 (the
/// coordinator's header limit is below the log's size) is sent again at once without the log, and then without asking
/// for the next lease. Transport
/// errors and retryable answers are retried with backoff up to `max_retry_wait` apart, until `give_up` gives a reason
/// (non-empty) to stop trying: asked between attempts and every 100 ms of a request under way, which it interrupts.
/// The upload then ends kDropped, logged as "giving up the upload of tile N of job J: REASON". With `next_lease`, the
/// upload also asks for the worker's next lease (protocol::kNextLeaseHeader), which the delivery then carries when the
/// coordinator granted one. Throws only what encoding throws.
Delivery upload_tile(client::HttpClient& http, const protocol::Lease& l, const std::string& worker_secret,
                     const std::string& prefix, const RenderResult& res, int width, int height,
                     const std::vector<std::string>& log, const std::optional<protocol::LeaseRequest>& next_lease,
                     std::chrono::milliseconds max_retry_wait, const std::function<std::string()>& give_up);

}  // namespace tessera::worker
