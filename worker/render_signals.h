// What a tile's render and the thread beside it share: the cancel flag and its reason, the rays so far, and the
// render's wish for its successor's lease.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>

namespace tessera::worker {

/// Why a tile's render was stopped early.
enum class Stop : int { kNone = 0, kRevoked = 1, kShutdown = 2 };

/// Made before the render and the thread beside it, shared by both. Thread-safe.
struct RenderSignals {
  std::atomic<bool> cancel{false};           ///< Set to stop the render.
  std::atomic<int> reason{int(Stop::kNone)};  ///< Why it was stopped (a Stop).
  std::atomic<uint64_t> rays{0};             ///< Rays the render has traced so far.

  /// The render is near its end: asks for the next lease, now or once someone is attached to ask (once per render).
  void want_next();
  /// Attaches who asks for the next lease, calling it at once if the render wanted it already; an empty function
  /// detaches, after which no call reaches the one attached before.
  void attach(std::function<void()> ask_next);

 private:
  std::mutex mutex_;
  std::function<void()> ask_next_;
  bool wants_next_ = false;
};

}  // namespace tessera::worker
