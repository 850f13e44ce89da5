#include "worker/render_signals.h"

#include <utility>

namespace tessera::worker {

void RenderSignals::want_next() {
  std::lock_guard lock(mutex_);
  if (wants_next_) return;
  wants_next_ = true;
  if (ask_next_) ask_next_();
}

void RenderSignals::attach(std::function<void()> ask_next) {
  std::lock_guard lock(mutex_);
  ask_next_ = std::move(ask_next);
  if (ask_next_ && wants_next_) ask_next_();
}

}  // namespace tessera::worker
