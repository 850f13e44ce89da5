// Delivers the webhook outbox (server/outbox.h) on threads of its own, never on the scheduler's or a request's: each
// due delivery is POSTed, signed (HMAC-SHA256 over the timestamp, ".", and the body), and recorded; an attempt without
// a 2xx answer is tried again after an exponential backoff with jitter, up to a number of attempts, then marked
// failed. A receiver that never answers holds one sender thread for the attempt's timeout, nothing else, and at most
// per_address threads at once; destruction ends the attempts under way at once (they are tried again after a
// restart).
#pragma once

#include "server/scheduler_types.h"
#include "server/webhook_post.h"
#include "server/webhook_log.h"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace tessera::server {

/// How deliveries are tried.
struct WebhookSenderOptions {
  std::string secret;                                ///< The HMAC key ("": deliveries go unsigned).
  int max_attempts = 8;                              ///< Attempts before a delivery is marked failed.
  std::chrono::milliseconds first_retry{1000};       ///< The wait before the second attempt; doubled for each next.
  std::chrono::milliseconds max_retry{300'000};      ///< The longest wait between attempts.
  std::chrono::milliseconds timeout{10'000};         ///< One attempt, connection to answer.
  int threads = 4;                                   ///< Deliveries under way at once.
  /// Deliveries to one address under way (or waiting for a thread) at once: a receiver that never answers holds at
  /// most this many threads, and deliveries to the others go on.
  int per_address = 2;
  std::chrono::milliseconds poll{250};               ///< How often the log is asked for due deliveries.
};

/// The lowercase hex HMAC-SHA256 of `message` keyed by `key`.
std::string hmac_sha256_hex(const std::string& key, const std::string& message);

/// The sender's threads over a delivery log, from construction to destruction.
class WebhookSender {
 public:
  /// Starts delivering from `log` (which must outlive it), reading the time from `clock`.
  WebhookSender(WebhookLog& log, WebhookSenderOptions options, ClockMs clock);
  ~WebhookSender();
  WebhookSender(const WebhookSender&) = delete;
  WebhookSender& operator=(const WebhookSender&) = delete;

  /// The wait before attempt `attempt` + 1 after `attempt` failed ones (1-based), jitter drawn from [w/2, w].
  std::chrono::milliseconds backoff(int64_t attempt);

 private:
  void dispatch();              // polls the log for due deliveries
  void deliver_loop();          // one sender thread
  void deliver(const DueDelivery& d);

  WebhookLog& log_;
  const WebhookSenderOptions opt_;
  ClockMs clock_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;                                   // (mu_)
  std::deque<DueDelivery> queue_;                       // due, not yet taken (mu_)
  std::set<std::pair<std::string, std::string>> busy_;  // queued or under way: (id, url) (mu_)
  std::map<std::string, int> per_address_;              // url -> how many of busy_ go there (mu_)
  uint64_t jitter_state_;                               // (mu_)
  PostStopper stopper_;                                 // ends the attempts under way at destruction
  std::vector<std::thread> threads_;
};

}  // namespace tessera::server
