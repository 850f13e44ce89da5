// The coordinator's helper threads (those that do not serve requests) and signals.
#pragma once

#include <pthread.h>
#include <signal.h>

namespace tessera::server {

/// Blocks every signal in the calling helper thread. Signals are for the threads that serve (asio's handler): with
/// SIGTERM left open in a helper, one arriving after the coordinator stopped listening for it would kill the process
/// while it closes its database.
inline void block_signals_in_helper_thread() {
  sigset_t all;
  sigfillset(&all);
  pthread_sigmask(SIG_BLOCK, &all, nullptr);
}

}  // namespace tessera::server
