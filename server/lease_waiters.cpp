#include "server/lease_waiters.h"

#include "server/helper_thread.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace tessera::server {

LeaseWaiters::LeaseWaiters() : thread_([this] { run(); }) {}

LeaseWaiters::~LeaseWaiters() {
  close();
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void LeaseWaiters::hold(std::chrono::steady_clock::time_point deadline, Attempt attempt, Expire expire) {
  {
    std::lock_guard lock(mutex_);
    if (!closed_) {
      held_.push_back(Held{deadline, std::move(attempt), std::move(expire)});
      // Tried once more on arrival: work noted between the request's own attempt and now found nothing held.
      work_ = true;
      cv_.notify_all();
      return;
    }
  }
  expire();
}

void LeaseWaiters::note_work() {
  std::lock_guard lock(mutex_);
  if (held_.empty()) return;
  work_ = true;
  cv_.notify_all();
}

void LeaseWaiters::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  cv_.notify_all();
}

std::size_t LeaseWaiters::held() {
  std::lock_guard lock(mutex_);
  return held_.size();
}

void LeaseWaiters::run() {
  block_signals_in_helper_thread();
  std::unique_lock lock(mutex_);
  for (;;) {
    if (held_.empty()) {  // after close() nothing is added: hold() expires at once
      if (stopping_) return;
      cv_.wait(lock, [&] { return stopping_ || !held_.empty(); });
      continue;
    }
    // Closed: everything held is expired now.
    if (closed_) {
      std::deque<Held> all = std::exchange(held_, {});
      lock.unlock();
      for (Held& h : all) h.expire();
      lock.lock();
      continue;
    }
    // Deadlines passed (held_ is in arrival order, not deadline order: every entry is checked).
    const auto now = std::chrono::steady_clock::now();
    std::vector<Expire> due;
    for (auto it = held_.begin(); it != held_.end();)
      if (it->deadline <= now) {
        due.push_back(std::move(it->expire));
        it = held_.erase(it);
      } else {
        ++it;
      }
    if (!due.empty()) {
      lock.unlock();
      for (Expire& e : due) e();
      lock.lock();
      continue;
    }
    // Work noted: the oldest requests are tried, each told how many this pass has answered, until one has nothing
    // to take (the rest would have nothing either, but for a worker kept from a job by its failures: the ones behind
    // it then wait for their deadline or the next note).
    if (work_) {
      work_ = false;
      for (int woken = 0; !held_.empty() && !closed_; ++woken) {
        Held h = std::move(held_.front());
        held_.pop_front();
        lock.unlock();
        const bool answered = h.attempt(woken);
        lock.lock();
        if (!answered) {
          held_.push_front(std::move(h));
          break;
        }
      }
      continue;
    }
    const auto next = std::min_element(held_.begin(), held_.end(), [](const Held& a, const Held& b) {
                        return a.deadline < b.deadline;
                      })->deadline;
    const std::size_t count = held_.size();
    cv_.wait_until(lock, next, [&] { return stopping_ || closed_ || work_ || held_.size() != count; });
  }
}

}  // namespace tessera::server
