// Webhooks (docs/protocol.md, "Webhooks"): the events the coordinator POSTs, the headers that sign them, and the
// delivery log GET /v1/webhooks/deliveries answers.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// The delivery's event id (the same for every attempt and destination: receivers de-duplicate by it).
inline constexpr std::string_view kWebhookIdHeader = "X-Tessera-Event-Id";
/// Milliseconds since the Unix epoch when the attempt was signed.
inline constexpr std::string_view kWebhookTimestampHeader = "X-Tessera-Timestamp";
/// "sha256=" and the lowercase hex HMAC-SHA256, keyed by the webhook secret, of the timestamp, ".", and the body.
inline constexpr std::string_view kWebhookSignatureHeader = "X-Tessera-Signature";

/// A frame of a sequence submitted with "notify_frames" was done (told to the job's own address only).
inline constexpr std::string_view kFrameDoneWebhookEvent = "frame.done";
/// The events a webhook is told of, as their names go in the body's "event".
inline constexpr std::string_view kWebhookEvents[] = {"job.done", "job.failed", "job.cancelled", "job.blocked",
                                                      kFrameDoneWebhookEvent};

/// One delivery of one event to one address, as the log keeps it.
struct WebhookDelivery {
  std::string id;                   ///< The event id.
  std::string url;                  ///< Where it goes.
  std::string event;                ///< e.g. "job.done".
  std::string job;                  ///< The job it is about.
  std::string state;                ///< "pending" (to be tried, maybe again), "delivered", or "failed" (gave up).
  int64_t attempts = 0;             ///< Attempts so far.
  int64_t created_ms = 0;           ///< When the event happened (stored with the change that caused it).
  std::optional<int64_t> next_ms;   ///< Pending: when the next attempt is due.
  std::optional<int> last_status;   ///< The HTTP status of the last answer (none: no answer).
  std::optional<std::string> last_error;  ///< Why the last attempt failed.
};
void to_json(nlohmann::json& j, const WebhookDelivery& d);
void from_json(const nlohmann::json& j, WebhookDelivery& d);

/// GET /v1/webhooks/deliveries: the most recent deliveries first.
struct WebhookDeliveryList {
  std::vector<WebhookDelivery> deliveries;  ///< At most the log's listing limit.
};
void to_json(nlohmann::json& j, const WebhookDeliveryList& l);
void from_json(const nlohmann::json& j, WebhookDeliveryList& l);

}  // namespace tessera::protocol
