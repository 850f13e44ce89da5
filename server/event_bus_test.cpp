// The event bus alone: order, bounded queues (a slow subscriber is dropped, publishing never waits), resuming from
// the ring with Last-Event-ID, the subscriber limit and closing.
#include "server/event_bus.h"
#include "server/farm_events.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <string>
#include <vector>

namespace tessera::server {
namespace {

// "e<i>" (built by appending: GCC 12 at -O3 warns falsely about "e" + std::to_string(i)).
std::string numbered(int i) {
  std::string s(1, 'e');
  s += std::to_string(i);
  return s;
}

std::vector<std::string> names(const Subscription::Batch& b) {
  std::vector<std::string> out;
  for (const Event& e : b.events) out.push_back(e.name);
  return out;
}

TEST(EventBus, EveryOpenSubscriberGetsEveryEventInOrder) {
  EventBus bus({}, "r1");
  auto a = bus.subscribe();
  bus.publish("one", "{}");
  auto b = bus.subscribe();  // sees only what comes after it
  bus.publish("two", "{\"n\":2}");
  bus.publish("three", "{}");
  const Subscription::Batch ba = a->take();
  EXPECT_EQ(names(ba), (std::vector<std::string>{"one", "two", "three"}));
  EXPECT_EQ(ba.events[0].id, "r1-1");
  EXPECT_EQ(ba.events[2].id, "r1-3");
  EXPECT_EQ(ba.events[1].data, "{\"n\":2}");
  EXPECT_EQ(ba.status, Subscription::Status::open);
  EXPECT_FALSE(ba.resync);
  EXPECT_EQ(names(b->take()), (std::vector<std::string>{"two", "three"}));
  EXPECT_TRUE(a->take().events.empty());
}

TEST(EventBus, WakeIsCalledForEachPublishAndAtOnceWhenSomethingWaits) {
  EventBus bus({}, "r");
  auto s = bus.subscribe();
  bus.publish("before", "{}");
  int wakes = 0;
  s->on_ready([&] { ++wakes; });
  EXPECT_EQ(wakes, 1);  // "before" was waiting
  bus.publish("after", "{}");
  EXPECT_EQ(wakes, 2);
  s->cancel();
  bus.publish("gone", "{}");
  EXPECT_EQ(wakes, 2);
}

TEST(EventBus, ASlowSubscriberIsDroppedWithoutHoldingUpOthers) {
  EventBusOptions o;
  o.queue_limit = 3;
  EventBus bus(o, "r");
  auto slow = bus.subscribe();
  auto fast = bus.subscribe();
  for (int i = 0; i < 10; ++i) {
    bus.publish(numbered(i), "{}");
    EXPECT_EQ(fast->take().events.size(), 1u);  // a reader that keeps up is never dropped
  }
  const Subscription::Batch b = slow->take();
  EXPECT_EQ(b.status, Subscription::Status::dropped);
  EXPECT_TRUE(b.events.empty());
  EXPECT_EQ(bus.subscribers(), 1u);
  EXPECT_EQ(fast->take().status, Subscription::Status::open);
}

TEST(EventBus, LastEventIdResumesFromTheRingOrAsksForAResync) {
  EventBusOptions o;
  o.ring = 4;
  EventBus bus(o, "run");
  for (int i = 1; i <= 6; ++i) bus.publish(numbered(i), "{}");  // the ring holds e3..e6
  auto resumed = bus.subscribe(std::string("run-4"));
  const Subscription::Batch b = resumed->take();
  EXPECT_FALSE(b.resync);
  EXPECT_EQ(names(b), (std::vector<std::string>{"e5", "e6"}));
  auto edge = bus.subscribe(std::string("run-2"));  // e3 onwards are all there
  EXPECT_EQ(names(edge->take()), (std::vector<std::string>{"e3", "e4", "e5", "e6"}));
  auto current = bus.subscribe(std::string("run-6"));
  const Subscription::Batch c = current->take();
  EXPECT_FALSE(c.resync);
  EXPECT_TRUE(c.events.empty());
  for (const char* stale : {"run-1", "other-5", "run-99", "run-x", "garbage", ""}) {
    auto s = bus.subscribe(std::string(stale));
    const Subscription::Batch r = s->take();
    EXPECT_TRUE(r.resync) << stale;
    EXPECT_TRUE(r.events.empty()) << stale;
  }
}

// A subscription limited to some event names gets only those, live and when resuming from the ring.
TEST(EventBus, ASubscriptionLimitedToSomeNamesGetsOnlyThose) {
  EventBus bus({}, "run");
  bus.publish("job", "{}");
  bus.publish("tile_done", "{}");
  auto live = bus.subscribe(std::nullopt, {"job"});
  auto resumed = bus.subscribe(std::string("run-0"), {"job", "worker_seen"});
  for (const char* name : {"tile_leased", "job", "tile_done", "worker_seen", "job"}) bus.publish(name, "{}");
  EXPECT_EQ(names(live->take()), (std::vector<std::string>{"job", "job"}));
  EXPECT_EQ(names(resumed->take()), (std::vector<std::string>{"job", "job", "worker_seen", "job"}));
}

TEST(EventBus, SubscriberLimitAndClose) {
  EventBusOptions o;
  o.max_subscribers = 2;
  EventBus bus(o, "r");
  auto a = bus.subscribe();
  auto b = bus.subscribe();
  EXPECT_EQ(bus.subscribe(), nullptr);
  b->cancel();
  auto c = bus.subscribe();
  ASSERT_NE(c, nullptr);
  std::atomic<int> woken{0};
  a->on_ready([&] { ++woken; });
  bus.close();
  EXPECT_EQ(woken, 1);
  EXPECT_EQ(a->take().status, Subscription::Status::closed);
  EXPECT_EQ(c->take().status, Subscription::Status::closed);
  EXPECT_EQ(bus.subscribe(), nullptr);
  bus.publish("late", "{}");
  EXPECT_TRUE(a->take().events.empty());
  EXPECT_EQ(EventBus(EventBusOptions{0, 8, 0}, "r").subscribe(), nullptr);  // a limit of 0 serves no stream
}

TEST(FarmEvents, JobStateChangesAreDedupedAndStaleSnapshotsAfterTheEndDropped) {
  EventBus bus({}, "r");
  FarmEvents events(bus);
  auto s = bus.subscribe();
  protocol::JobStatus j;
  j.id = "j-1";
  events.job(j);                           // submitted: queued
  events.job_if_state_changed(j);          // still queued: nothing
  j.state = protocol::JobState::running;
  events.job_if_state_changed(j);          // first lease: running
  events.job_if_state_changed(j);
  j.state = protocol::JobState::done;
  events.job(j);
  j.state = protocol::JobState::running;   // a snapshot taken before the end, published late
  events.job_if_state_changed(j);
  const Subscription::Batch b = s->take();
  ASSERT_EQ(b.events.size(), 3u);
  EXPECT_EQ(nlohmann::json::parse(b.events[0].data)["state"], "queued");
  EXPECT_EQ(nlohmann::json::parse(b.events[1].data)["state"], "running");
  EXPECT_EQ(nlohmann::json::parse(b.events[2].data)["state"], "done");
}

TEST(FarmEvents, WorkersLostAndBackFromPeriodicLooks) {
  EventBus bus({}, "r");
  FarmEvents events(bus);
  auto s = bus.subscribe();
  protocol::WorkerInfo w;
  w.id = "w-1";
  events.worker_registered(w);
  events.workers_checked({w});
  w.state = protocol::WorkerState::offline;
  events.workers_checked({w});
  events.workers_checked({w});
  w.state = protocol::WorkerState::rendering;
  events.workers_checked({w});
  const Subscription::Batch b = s->take();
  ASSERT_EQ(names(b), (std::vector<std::string>{"worker_seen", "worker_lost", "worker_seen"}));
  EXPECT_EQ(nlohmann::json::parse(b.events[0].data)["reason"], "registered");
  EXPECT_EQ(nlohmann::json::parse(b.events[1].data)["reason"], "offline");
  EXPECT_EQ(nlohmann::json::parse(b.events[2].data)["reason"], "back");
  EXPECT_EQ(nlohmann::json::parse(b.events[2].data)["worker"]["id"], "w-1");
}

}  // namespace
}  // namespace tessera::server
