#include "server/group_commit.h"

#include <pthread.h>
#include <signal.h>

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
  return stats_;
}

void GroupCommit::loop() {
  // Signals are for the threads that serve (asio's handler): with SIGTERM left open here, one arriving after the
  // coordinator stopped listening for it would kill the process while it closes its database.
  sigset_t all;
  sigfillset(&all);
  pthread_sigmask(SIG_BLOCK, &all, nullptr);
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
