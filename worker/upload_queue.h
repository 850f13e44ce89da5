// The worker's uploads in the background: a finished tile is encoded and sent on a thread of its own while the
// worker leases and renders the next one, so a tile's upload costs the render loop nothing.
#pragma once

#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace tessera::worker {

/// Runs one task at a time on a background thread. post() waits until the previous task has finished before it
/// hands over the next, so at most one task (one finished tile) is outstanding: the worker never runs ahead of its
/// uploads by more than the tile it is rendering. Thread-safe.
class UploadQueue {
 public:
  UploadQueue();
  /// Waits for the task in flight, then stops the thread.
  ~UploadQueue();
  UploadQueue(const UploadQueue&) = delete;
  UploadQueue& operator=(const UploadQueue&) = delete;

  /// Waits until no task is in flight, then starts `task` on the background thread. What the task throws is its own
  /// business: it must catch everything.
  void post(std::function<void()> task);
  /// Returns once no task is in flight.
  void wait_idle();

 private:
  void loop();

  std::mutex mutex_;
  std::condition_variable cv_;
  std::function<void()> task_;  // set: in flight (waiting to start or running)
  bool stopping_ = false;
  std::thread thread_;  // last: starts after every other member is ready
};

}  // namespace tessera::worker
