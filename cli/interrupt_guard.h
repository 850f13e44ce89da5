// Ctrl-C and SIGTERM turned into a flag that long-running commands poll (`render`, `render --workers`).
#pragma once

#include <atomic>
#include <csignal>

namespace tessera::cli {

/// Installs SIGINT and SIGTERM handlers that set interrupted() for the lifetime of the object, and restores the
/// previous handlers after. The flag is cleared when the outermost guard is made: a guard made inside another (a
/// sequence's frame inside the sequence) keeps a signal that arrived before it. Made and dropped on one thread.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

  /// The flag the handlers set (e.g. for RenderOptions::cancel).
  static const std::atomic<bool>& flag();
  /// True once a signal arrived while a guard was installed.
  static bool interrupted() { return flag().load(); }

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

}  // namespace tessera::cli
