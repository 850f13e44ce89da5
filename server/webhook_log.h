// Where webhook deliveries are kept between attempts: the outbox rows the scheduler stored, their attempts and
// answers. Implemented by the coordinator's stores (server/database.h, server/memory_store.h).
#pragma once

#include "protocol/webhook.h"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace tessera::server {

/// A delivery whose next attempt is due.
struct DueDelivery {
  std::string id;        ///< The event id.
  std::string url;       ///< Where it goes.
  std::string body;      ///< What is POSTed.
  int64_t attempts = 0;  ///< Attempts before this one.
};

/// The outcome of one attempt.
struct DeliveryAttempt {
  std::string state;                 ///< "delivered", "pending" (tried again at next_ms) or "failed" (given up).
  std::optional<int64_t> next_ms;    ///< pending: when to try again.
  std::optional<int> status;         ///< The HTTP status answered, if any.
  std::optional<std::string> error;  ///< Why it did not count as delivered.
};

/// The delivery log.
class WebhookLog {
 public:
  virtual ~WebhookLog() = default;
  /// Pending deliveries due at `now` (next attempt at or before it), oldest first, at most `limit`, none to the
  /// addresses in `skip`.
  virtual std::vector<DueDelivery> due_deliveries(int64_t now, size_t limit, const std::set<std::string>& skip) = 0;
  /// Records an attempt of the delivery of event `id` to `url`.
  virtual void record_attempt(const std::string& id, const std::string& url, const DeliveryAttempt& attempt) = 0;
  /// The most recent deliveries first, at most `limit`.
  virtual std::vector<protocol::WebhookDelivery> deliveries(size_t limit) = 0;
};

}  // namespace tessera::server
