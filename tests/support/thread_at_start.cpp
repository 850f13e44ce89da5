// A library for LD_PRELOAD in tests: its constructor starts a thread that sleeps for the life of the process, so that
// the program under test is never single-threaded (`render --workers` must then start its workers with exec, not
// fork them: tests/farm/render_exec_workers.sh).
#include <chrono>
#include <thread>

namespace {

struct StartsAThread {
  StartsAThread() {
    std::thread([] {
      for (;;) std::this_thread::sleep_for(std::chrono::hours(1));
    }).detach();
  }
} starts_a_thread;

}  // namespace
