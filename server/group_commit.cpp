#include "server/group_commit.h"

#include "server/helper_thread.h"

#include <future>
#include <utility>

namespace tessera::server {

GroupCommit::GroupCommit(std::function<void()> flush) : flush_(std::move(flush)), thread_([this] { loop(); }) {}

GroupCommit::~GroupCommit() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void GroupCommit::after_flush(std::function<void()> then) {
  {
    std::lock_guard lock(mu_);
    waiting_.push_back(std::move(then));
  }
  cv_.notify_one();
}

void GroupCommit::flush() {
  std::promise<void> done;
  std::future<void> flushed = done.get_future();
  after_flush([&done] { done.set_value(); });
  flushed.wait();
}

GroupCommitStats GroupCommit::stats() {
  std::lock_guard lock(mu_);
  GroupCommitStats s = stats_;
  s.queued = waiting_.size();
  return s;
}

void GroupCommit::loop() {
  block_signals_in_helper_thread();
  std::unique_lock lock(mu_);
  for (;;) {
    cv_.wait(lock, [&] { return stopping_ || !waiting_.empty(); });
    if (waiting_.empty()) return;  // stopping, nothing left
    // Everything handed over until now was committed before this flush begins; later arrivals wait for the next.
    std::vector<std::function<void()>> batch;
    batch.swap(waiting_);
    lock.unlock();
    flush_();
    lock.lock();
    ++stats_.flushes;
    stats_.acknowledged += batch.size();
    lock.unlock();
    for (auto& then : batch) then();
    lock.lock();
  }
}

}  // namespace tessera::server
