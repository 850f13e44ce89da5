// The coordinator of `render --workers`, run in the command's own process: no process to start, link and stop.
#pragma once

#include "server/coordinator.h"

#include <atomic>
#include <mutex>
#include <string>
#include <thread>

namespace tessera::cli {

/// A server::Coordinator built and run on a thread of its own (so that the command goes on while it opens its folder),
/// with SIGINT and SIGTERM blocked on its threads (the command's thread takes them). The destructor stops it (as
/// Coordinator::stop: requests in flight finish) and waits for its threads.
class PrivateCoordinator {
 public:
  /// Starts building the coordinator of `options` (which should listen on an inherited socket, listen_fd, so that its
  /// address is known before it is built).
  explicit PrivateCoordinator(server::CoordinatorOptions options);
  ~PrivateCoordinator();
  PrivateCoordinator(const PrivateCoordinator&) = delete;
  PrivateCoordinator& operator=(const PrivateCoordinator&) = delete;

  /// True once the coordinator has stopped serving (or could not be built): a farm without it cannot go on.
  bool ended() const { return ended_.load(); }
  /// Why it ended early: what its construction or run() threw ("" when it did not).
  std::string error() const;

 private:
  void serve(server::CoordinatorOptions options);

  mutable std::mutex mutex_;
  server::Coordinator* running_ = nullptr;  // while run() serves
  bool stopping_ = false;
  std::string error_;
  std::atomic<bool> ended_{false};
  std::thread thread_;  // last: started once the members above exist
};

}  // namespace tessera::cli
