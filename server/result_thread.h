// Where the coordinator writes finished jobs' results: one thread of their own, one result at a time, its encoding on
// that thread alone (a one-thread task arena) and at a lower CPU priority, so that a large image's compression never
// takes the cores that serve requests. Uploads and leases go on being answered while a result is written.
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <tbb/task_arena.h>

#include <functional>

namespace tessera::server {

/// The results' thread.
class ResultThread {
 public:
  /// The nice value (added to the process's) that the thread runs at.
  static constexpr int kNice = 5;

  ResultThread() = default;
  ResultThread(const ResultThread&) = delete;
  ResultThread& operator=(const ResultThread&) = delete;
  /// Drops the work not begun and waits for the work under way.
  ~ResultThread();

  /// Queues `work`, run after the work queued before it.
  void post(std::function<void()> work);
  /// Waits until the queued work is done (nothing is posted meanwhile).
  void join();

 private:
  boost::asio::thread_pool pool_{1};
  tbb::task_arena arena_{1};
};

}  // namespace tessera::server
