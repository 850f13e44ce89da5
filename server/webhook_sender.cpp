#include "server/webhook_sender.h"

#include "failpoint/failpoint.h"
#include "protocol/webhook.h"
#include "server/helper_thread.h"
#include "server/webhook_post.h"
#include "server/webhook_url.h"

#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <random>

namespace tessera::server {

std::string hmac_sha256_hex(const std::string& key, const std::string& message) {
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  HMAC(EVP_sha256(), key.data(), int(key.size()), reinterpret_cast<const unsigned char*>(message.data()),
       message.size(), mac, &len);
  static const char* kHex = "0123456789abcdef";
  std::string out;
  for (unsigned int i = 0; i < len; ++i) {
    out += kHex[mac[i] >> 4];
    out += kHex[mac[i] & 15];
  }
  return out;
}

WebhookSender::WebhookSender(WebhookLog& log, WebhookSenderOptions options, ClockMs clock)
    : log_(log), opt_(std::move(options)), clock_(std::move(clock)), jitter_state_(std::random_device{}()) {
  threads_.emplace_back([this] { dispatch(); });
  for (int i = 0; i < std::max(1, opt_.threads); ++i) threads_.emplace_back([this] { deliver_loop(); });
}

WebhookSender::~WebhookSender() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  stopper_.stop();
  cv_.notify_all();
  for (std::thread& t : threads_) t.join();
}

std::chrono::milliseconds WebhookSender::backoff(int64_t attempt) {
  const int64_t shift = std::clamp<int64_t>(attempt - 1, 0, 30);
  const int64_t wait = std::min<int64_t>(opt_.first_retry.count() << shift, opt_.max_retry.count());
  std::lock_guard lock(mu_);
  jitter_state_ = jitter_state_ * 6364136223846793005ull + 1442695040888963407ull;
  const double u = double(jitter_state_ >> 11) / double(uint64_t(1) << 53);  // [0, 1)
  return std::chrono::milliseconds(wait / 2 + int64_t(u * double(wait - wait / 2)));
}

void WebhookSender::dispatch() {
  block_signals_in_helper_thread();
  std::unique_lock lock(mu_);
  const int cap = std::max(1, opt_.per_address);
  while (!stop_) {
    // Addresses with as many deliveries under way as they may have are skipped: one that never answers cannot fill
    // the batch (and the threads) while others' deliveries are due.
    std::set<std::string> full;
    for (const auto& [url, n] : per_address_)
      if (n >= cap) full.insert(url);
    lock.unlock();
    std::vector<DueDelivery> due;
    try {
      due = log_.due_deliveries(clock_(), 64, full);
    } catch (const std::exception& e) {
      spdlog::warn("webhooks: cannot read the outbox: {}", e.what());
    }
    lock.lock();
    for (DueDelivery& d : due) {
      int& n = per_address_[d.url];
      if (n < cap && busy_.emplace(d.id, d.url).second) {
        ++n;
        queue_.push_back(std::move(d));
      } else if (n == 0) {
        per_address_.erase(d.url);
      }
    }
    if (!queue_.empty()) cv_.notify_all();
    cv_.wait_for(lock, opt_.poll, [this] { return stop_; });
  }
}

void WebhookSender::deliver_loop() {
  block_signals_in_helper_thread();
  std::unique_lock lock(mu_);
  while (true) {
    cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    DueDelivery d = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    deliver(d);
    lock.lock();
    busy_.erase({d.id, d.url});
    if (--per_address_[d.url] <= 0) per_address_.erase(d.url);
  }
}

void WebhookSender::deliver(const DueDelivery& d) {
  TESSERA_FAIL_POINT("webhook.deliver");
  const std::string timestamp = std::to_string(clock_());
  std::vector<std::pair<std::string, std::string>> headers{{std::string(protocol::kWebhookIdHeader), d.id},
                                                           {std::string(protocol::kWebhookTimestampHeader), timestamp}};
  if (!opt_.secret.empty())
    headers.emplace_back(std::string(protocol::kWebhookSignatureHeader),
                         "sha256=" + hmac_sha256_hex(opt_.secret, timestamp + "." + d.body));
  PostAnswer answer;
  try {
    answer = post_webhook(parse_webhook_url(d.url), d.body, headers, opt_.timeout, &stopper_);
  } catch (const std::exception& e) {  // an address stored by a build that read it otherwise
    answer.error = e.what();
  }
  if (!answer.status && answer.error == "stopped") return;  // shutting down: not an attempt, the row stays due
  DeliveryAttempt a;
  a.status = answer.status;
  const int64_t attempts = d.attempts + 1;
  if (answer.status && *answer.status >= 200 && *answer.status < 300) {
    a.state = "delivered";
  } else {
    a.error = answer.status ? "answered " + std::to_string(*answer.status) : answer.error;
    if (attempts >= opt_.max_attempts) {
      a.state = "failed";
      spdlog::warn("webhook {} to {}: gave up after {} attempts: {}", d.id, d.url, attempts, *a.error);
    } else {
      a.state = "pending";
      a.next_ms = clock_() + backoff(attempts).count();
    }
  }
  try {
    log_.record_attempt(d.id, d.url, a);
  } catch (const std::exception& e) {
    spdlog::warn("webhook {} to {}: cannot record the attempt ({}); it is tried again", d.id, d.url, e.what());
  }
}

}  // namespace tessera::server
