#include "server/event_bus.h"

#include <charconv>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <utility>

namespace tessera::server {

struct EventBus::Core {
  EventBusOptions opt;
  std::string run;
  mutable std::mutex mu;
  uint64_t last = 0;                 // number of the newest event
  std::deque<Event> ring;            // the newest opt.ring events
  std::vector<Subscription*> subs;   // open subscriptions (each removes itself)
  bool closed = false;
};

namespace {

// The n of "<run>-<n>" when `id` is from this run, else nothing.
std::optional<uint64_t> event_number(const std::string& id, const std::string& run) {
  if (id.size() <= run.size() + 1 || id.compare(0, run.size(), run) != 0 || id[run.size()] != '-') return std::nullopt;
  uint64_t n = 0;
  const char* first = id.data() + run.size() + 1;
  const char* end = id.data() + id.size();
  const auto [ptr, ec] = std::from_chars(first, end, n);
  if (ec != std::errc() || ptr != end) return std::nullopt;
  return n;
}

void call_all(const std::vector<std::function<void()>>& wakes) {
  for (const auto& w : wakes) w();
}

}  // namespace

EventBus::EventBus(EventBusOptions options, std::string run) : core_(std::make_shared<Core>()) {
  if (run.empty() || run.find('-') != std::string::npos) throw std::invalid_argument("an event run tag must be non-empty without '-'");
  core_->opt = options;
  core_->run = std::move(run);
}

EventBus::~EventBus() { close(); }

void EventBus::publish(std::string name, std::string data) {
  std::vector<std::function<void()>> wakes;
  {
    std::lock_guard lock(core_->mu);
    if (core_->closed) return;
    Event e{core_->run + "-" + std::to_string(++core_->last), std::move(name), std::move(data)};
    for (Subscription* s : core_->subs) {
      if (s->status_ != Subscription::Status::open || !s->wants(e)) continue;
      if (s->queue_.size() >= core_->opt.queue_limit) {
        s->status_ = Subscription::Status::dropped;
        s->queue_.clear();
      } else {
        s->queue_.push_back(e);
      }
      if (s->wake_) wakes.push_back(s->wake_);
    }
    if (core_->opt.ring > 0) {
      core_->ring.push_back(std::move(e));
      if (core_->ring.size() > core_->opt.ring) core_->ring.pop_front();
    }
  }
  call_all(wakes);
}

std::shared_ptr<Subscription> EventBus::subscribe(const std::optional<std::string>& last_event_id,
                                                  std::set<std::string> only) {
  std::lock_guard lock(core_->mu);
  if (core_->closed || core_->subs.size() >= core_->opt.max_subscribers) return nullptr;
  auto s = std::make_shared<Subscription>(core_, false);
  s->only_ = std::move(only);
  if (last_event_id) {
    const std::optional<uint64_t> n = event_number(*last_event_id, core_->run);
    const uint64_t oldest = core_->ring.empty() ? core_->last + 1 : core_->last + 1 - core_->ring.size();
    // Resumable when every event after n is still in the ring (n + 1 >= oldest) and n is not in the future.
    if (!n || *n > core_->last || *n + 1 < oldest) {
      s->resync_ = true;
    } else {
      for (const Event& e : core_->ring)
        if (*event_number(e.id, core_->run) > *n && s->wants(e)) s->queue_.push_back(e);
    }
  }
  core_->subs.push_back(s.get());
  return s;
}

void EventBus::close() {
  std::vector<std::function<void()>> wakes;
  {
    std::lock_guard lock(core_->mu);
    core_->closed = true;
    for (Subscription* s : core_->subs) {
      s->status_ = Subscription::Status::closed;
      if (s->wake_) wakes.push_back(s->wake_);
    }
    core_->subs.clear();
  }
  call_all(wakes);
}

std::size_t EventBus::subscribers() const {
  std::lock_guard lock(core_->mu);
  std::size_t n = 0;
  for (const Subscription* s : core_->subs) n += s->status_ == Subscription::Status::open;
  return n;
}

const EventBusOptions& EventBus::options() const { return core_->opt; }

Subscription::Subscription(std::shared_ptr<EventBus::Core> core, bool resync) : core_(std::move(core)), resync_(resync) {}

Subscription::~Subscription() { cancel(); }

void Subscription::on_ready(std::function<void()> wake) {
  bool now = false;
  {
    std::lock_guard lock(core_->mu);
    wake_ = wake;
    now = !queue_.empty() || resync_ || status_ != Status::open;
  }
  if (now && wake) wake();
}

Subscription::Batch Subscription::take() {
  std::lock_guard lock(core_->mu);
  Batch b;
  b.events.swap(queue_);
  b.resync = std::exchange(resync_, false);
  b.status = status_;
  return b;
}

void Subscription::end() {
  std::function<void()> wake;
  {
    std::lock_guard lock(core_->mu);
    if (status_ == Status::open) status_ = Status::closed;
    wake = std::move(wake_);
    wake_ = nullptr;
    std::erase(core_->subs, this);
  }
  if (wake) wake();
}

void Subscription::cancel() {
  std::lock_guard lock(core_->mu);
  if (status_ == Status::open) status_ = Status::closed;
  wake_ = nullptr;
  std::erase(core_->subs, this);
}

}  // namespace tessera::server
