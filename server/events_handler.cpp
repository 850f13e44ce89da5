#include "server/events_handler.h"

#include "protocol/events.h"
#include "protocol/query.h"
#include "protocol/routes.h"

#include <spdlog/spdlog.h>

#include <memory>
#include <optional>
#include <string>
#include <utility>

namespace tessera::server {

namespace {

// A subscription written as SSE: its events in order; a resync event when events were missed; the end when the
// subscriber was dropped (it fell behind) or the bus closed.
class SseStream final : public BodyStream {
 public:
  SseStream(std::shared_ptr<Subscription> sub, std::size_t queue_limit) : sub_(std::move(sub)), queue_limit_(queue_limit) {}
  ~SseStream() override { sub_->cancel(); }

  void start(std::function<void()> ready) override { sub_->on_ready(std::move(ready)); }

  Chunk next() override {
    Chunk c;
    if (!started_) {
      started_ = true;
      c.text = "retry: 1000\n\n";  // a reconnecting EventSource-like client waits a second
    }
    Subscription::Batch b = sub_->take();
    if (b.resync) c.text += std::string("event: ") + protocol::events::kResync + "\ndata: {}\n\n";
    for (const Event& e : b.events) c.text += sse_message(e);
    if (b.status == Subscription::Status::dropped) {
      spdlog::warn("event stream dropped: its client fell behind by {} events", queue_limit_);
      c.text += ": dropped: this client fell behind; reconnect with Last-Event-ID\n\n";
    }
    c.last = b.status != Subscription::Status::open;
    return c;
  }

  void stop() override { sub_->cancel(); }

  std::string idle_text() const override { return ": keep-alive\n\n"; }


 private:
  std::shared_ptr<Subscription> sub_;
  std::size_t queue_limit_;
  bool started_ = false;
};

}  // namespace

std::string sse_message(const Event& e) { return "id: " + e.id + "\nevent: " + e.name + "\ndata: " + e.data + "\n\n"; }

size_t EventsHandler::end_unless(const std::function<bool(const std::string&)>& admitted) {
  std::vector<std::shared_ptr<Subscription>> ending;
  {
    std::lock_guard lock(mu_);
    std::erase_if(open_, [&](const auto& entry) {
      std::shared_ptr<Subscription> sub = entry.second.lock();
      if (!sub) return true;
      if (admitted(entry.first)) return false;
      ending.push_back(std::move(sub));
      return true;
    });
  }
  for (const auto& sub : ending) sub->end();  // outside the lock: ending wakes the stream's writer
  return ending.size();
}

HttpReply EventsHandler::open(const HttpRequest& req, const std::string& credential) {
  std::optional<std::string> last;
  if (const auto h = req["Last-Event-ID"]; !h.empty()) last = std::string(h);
  std::shared_ptr<Subscription> sub = bus_.subscribe(last, protocol::parse_event_filter(req.target()));
  if (!sub) {
    const std::size_t limit = bus_.options().max_subscribers;
    HttpResponse res = json_error(http::status::service_unavailable,
                                  limit == 0 ? std::string("this coordinator serves no event streams (--max-event-streams 0); poll GET " + protocol::routes::jobs())
                                             : "too many event streams (the limit is " + std::to_string(limit) + "); retry later or poll GET " + protocol::routes::jobs(),
                                  req.version());
    res.set(http::field::retry_after, "5");
    return {std::move(res), nullptr};
  }
  {
    std::lock_guard lock(mu_);
    std::erase_if(open_, [](const auto& entry) { return entry.second.expired(); });
    open_.emplace_back(credential, sub);
  }
  auto stream = std::make_shared<SseStream>(std::move(sub), bus_.options().queue_limit);
  HttpResponse head{http::status::ok, req.version()};
  head.set(http::field::content_type, "text/event-stream; charset=utf-8");
  head.set(http::field::cache_control, "no-store");
  head.set("X-Accel-Buffering", "no");  // proxies that buffer answers pass this one on as it comes
  return {std::move(head), std::move(stream)};
}

}  // namespace tessera::server
