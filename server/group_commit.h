// Group commit: acknowledgements that wait for the disk share one flush. One thread flushes the write-ahead log for
// every request that arrived while the previous flush ran, then hands each its continuation; nobody else waits.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace tessera::server {

/// Flushes and acknowledgements served so far.
struct GroupCommitStats {
  uint64_t flushes = 0;        ///< Calls of the flush function that returned.
  uint64_t acknowledged = 0;   ///< Continuations run after them.
  uint64_t queued = 0;         ///< Continuations handed over that wait for a flush not yet begun.
};

/// Runs continuations once everything committed before they were handed over is on the disk. Thread-safe.
class GroupCommit {
 public:
  /// A group commit over `flush`, which makes everything committed so far durable (or does not return: a failed
  /// flush stops the process). `flush` runs on this object's own thread only.
  explicit GroupCommit(std::function<void()> flush);
  /// Serves what is queued (one last flush), then stops the thread.
  ~GroupCommit();
  GroupCommit(const GroupCommit&) = delete;
  GroupCommit& operator=(const GroupCommit&) = delete;

  /// Runs `then` on the flushing thread after a flush that began after this call: everything committed before the
  /// call is durable by then. `then` must be quick (e.g. post an answer) and must not throw.
  void after_flush(std::function<void()> then);
  /// Returns once everything committed before the call is durable (after_flush, waited for).
  void flush();
  /// Counts so far.
  GroupCommitStats stats();

 private:
  void loop();

  std::function<void()> flush_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::function<void()>> waiting_;  // handed over since the running flush began
  bool stopping_ = false;
  GroupCommitStats stats_;
  std::thread thread_;  // last: starts after every other member is ready
};

}  // namespace tessera::server
