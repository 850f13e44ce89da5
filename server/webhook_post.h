// One webhook attempt on the wire: a JSON POST to an http:// or https:// address (certificates checked against the
// system's roots), the whole attempt bounded by a timeout, the answer's status read and its body dropped.
#pragma once

#include "server/webhook_url.h"

#include <chrono>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace tessera::server {

/// What a POST came to.
struct PostAnswer {
  std::optional<int> status;  ///< The HTTP status (none: no answer).
  std::string error;          ///< Why there was no answer (connection refused, timed out, TLS).
};

/// POSTs `body` (application/json) with `headers` to `url`, giving up after `timeout`; never throws.
PostAnswer post_webhook(const WebhookUrl& url, const std::string& body,
                        const std::vector<std::pair<std::string, std::string>>& headers,
                        std::chrono::milliseconds timeout);

}  // namespace tessera::server
