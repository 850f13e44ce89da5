// Lease requests held while no tile is leasable for their worker (a request's wait_ms): each is answered as soon as
// the scheduler notes new work that its worker may take, at its deadline, or at shutdown.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace tessera::server {

/// Holds lease requests on a thread of its own. Thread-safe.
class LeaseWaiters {
 public:
  /// Tries to answer a held request, `woken` requests having been answered in the same pass before it: true when it
  /// answered, false when there is (still) nothing for it. Called on this object's thread, never with its lock held.
  using Attempt = std::function<bool(int woken)>;
  /// Answers a held request at its deadline or at shutdown (called once, when no attempt answered it).
  using Expire = std::function<void()>;

  LeaseWaiters();
  /// Answers every held request with its Expire, then stops the thread.
  ~LeaseWaiters();
  LeaseWaiters(const LeaseWaiters&) = delete;
  LeaseWaiters& operator=(const LeaseWaiters&) = delete;

  /// Holds a request until `deadline`, trying `attempt` on arrival and each time work is noted; once closed, expires
  /// it at once.
  void hold(std::chrono::steady_clock::time_point deadline, Attempt attempt, Expire expire);
  /// New work may be leasable: the held requests are tried, oldest first, until one finds none. Never blocks on the
  /// held requests (the scheduler calls it under its lock).
  void note_work();
  /// Expires every held request and every later one (at shutdown).
  void close();
  /// Requests held now.
  std::size_t held();

 private:
  struct Held {
    std::chrono::steady_clock::time_point deadline;
    Attempt attempt;
    Expire expire;
  };
  void run();

  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Held> held_;  // oldest first
  bool work_ = false;      // noted since the thread last looked
  bool closed_ = false;
  bool stopping_ = false;
  std::thread thread_;  // last: starts after every other member is ready
};

}  // namespace tessera::server
