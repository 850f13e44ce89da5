// One webhook attempt on the wire: a JSON POST to an http:// or https:// address (certificates checked against the
// system's roots), the whole attempt, connection to answer, bounded by a timeout, the answer's status read and its
// body dropped. Attempts under way can be stopped from another thread (at shutdown).
#pragma once

#include "server/webhook_url.h"

#include <boost/asio/io_context.hpp>

#include <chrono>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace tessera::server {

/// What a POST came to.
struct PostAnswer {
  std::optional<int> status;  ///< The HTTP status (none: no answer).
  std::string error;          ///< Why there was no answer (connection refused, timed out, TLS, stopped).
};

/// Stops the attempts under way and every later one at once (thread-safe).
class PostStopper {
 public:
  /// Ends every attempt under way with "stopped" and makes later ones end so at once.
  void stop();

 private:
  friend PostAnswer post_webhook(const WebhookUrl&, const std::string&,
                                 const std::vector<std::pair<std::string, std::string>>&, std::chrono::milliseconds,
                                 PostStopper*);
  bool enter(boost::asio::io_context* ioc);  // false once stopped
  bool leave(boost::asio::io_context* ioc);  // true when stopped meanwhile
  std::mutex mu_;
  bool stopped_ = false;                      // (mu_)
  std::set<boost::asio::io_context*> running_;  // (mu_)
};

/// POSTs `body` (application/json) with `headers` to `url`, giving up after `timeout` or when `stopper` (if any) is
/// stopped; never throws.
PostAnswer post_webhook(const WebhookUrl& url, const std::string& body,
                        const std::vector<std::pair<std::string, std::string>>& headers,
                        std::chrono::milliseconds timeout, PostStopper* stopper = nullptr);

}  // namespace tessera::server
