// The coordinator's event feed (GET /v1/events): handlers publish what changed; each subscriber gets the events in
// order through its own bounded queue. Publishing never waits for a subscriber: one whose queue is full is dropped
// (it reconnects and resumes). A bounded ring of recent events lets a reconnecting subscriber resume after the last
// event it saw. Knows nothing of HTTP.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// One published event.
struct Event {
  std::string id;    ///< "<run>-<n>": n counts up from 1 in this run; run differs between coordinator runs.
  std::string name;  ///< e.g. "job", "tile_done" (docs/protocol.md, "Events").
  std::string data;  ///< One line of JSON.
};

/// Sizes of an event bus.
struct EventBusOptions {
  std::size_t ring = 4096;            ///< Recent events kept for resuming subscribers.
  std::size_t queue_limit = 1024;     ///< Events waiting for one subscriber; one more drops it.
  std::size_t max_subscribers = 64;   ///< Open subscriptions (0: none are accepted).
};

class Subscription;

/// Publishes events to subscribers. Thread-safe.
class EventBus {
 public:
  /// A bus whose event ids start with `run` (which must not contain '-'; a random tag per coordinator run).
  EventBus(EventBusOptions options, std::string run);
  ~EventBus();
  EventBus(const EventBus&) = delete;
  EventBus& operator=(const EventBus&) = delete;

  /// Appends an event to the ring and to every subscriber's queue (dropping subscribers whose queue is full).
  void publish(std::string name, std::string data);
  /// A new subscription, or nullptr when max_subscribers are open or the bus is closed. With `last_event_id`, the
  /// queue starts with the events after it from the ring; when they are no longer all there (or the id is from
  /// another run or malformed), the subscription starts with needs_resync set instead.
  /// With `only` not empty, the subscription gets just the events of those names (and resync).
  std::shared_ptr<Subscription> subscribe(const std::optional<std::string>& last_event_id = std::nullopt,
                                          std::set<std::string> only = {});
  /// Ends every subscription (their status becomes closed) and refuses new ones.
  void close();
  /// Open subscriptions.
  std::size_t subscribers() const;
  /// The options it runs with.
  const EventBusOptions& options() const;

  struct Core;  ///< Shared with subscriptions (opaque).

 private:
  std::shared_ptr<Core> core_;
};

/// One subscriber's queue. Thread-safe.
class Subscription {
 public:
  /// Open: events may come; dropped: it fell behind by queue_limit events; closed: the bus closed or it was cancelled.
  enum class Status { open, dropped, closed };
  /// What take() hands over.
  struct Batch {
    std::vector<Event> events;  ///< Queued events, oldest first.
    bool resync = false;        ///< Events were missed before these: reload the state (e.g. GET /v1/jobs).
    Status status = Status::open;  ///< After these events.
  };

  Subscription(std::shared_ptr<EventBus::Core> core, bool resync);
  ~Subscription();
  Subscription(const Subscription&) = delete;
  Subscription& operator=(const Subscription&) = delete;

  /// Sets the function called (from a publishing thread, without locks held) whenever events are queued or the
  /// status changes; it must not block. Called once at once when something is already waiting.
  void on_ready(std::function<void()> wake);
  /// Takes every queued event and the status.
  Batch take();
  /// Leaves the bus (status closed); idempotent.
  void cancel();
  /// Leaves the bus and wakes the reader, whose next take() says closed (its stream ends); idempotent.
  void end();

 private:
  friend class EventBus;
  std::shared_ptr<EventBus::Core> core_;
  // Guarded by the bus's lock.
  std::vector<Event> queue_;
  std::set<std::string> only_;  // the event names it gets (empty: all); set before it is shared
  bool wants(const Event& e) const { return only_.empty() || only_.count(e.name) > 0; }
  bool resync_ = false;
  Status status_ = Status::open;
  std::function<void()> wake_;
};

}  // namespace tessera::server
