// Linked into the unit tests of the ThreadSanitizer build only (TESSERA_TSAN). Debian's oneTBB is not built with
// TSan: its task pool hands parallel_for tasks between threads through synchronisation TSan cannot see, so every
// parallel render is reported as a race inside TBB's headers. TBB is therefore held to the calling thread here
// (renders stay bitwise the same for any thread count), and TSan watches the threads the coordinator and the
// worker start themselves: the HTTP server's, the heartbeat thread, the tests' clients, and the locks between them.
//
// One TBB hand-off remains: a worker with two threads begins a tile's render ahead of its turn by enqueueing it into
// its task arena (worker/worker.cpp, Worker::head_start), and TBB runs an enqueued task on a thread of its own even
// when held to one thread. The task, its render and what it leaves for the render loop pass between threads through
// TBB alone, so accesses made inside that task are not reported; everything around it (the heartbeat thread that
// asks for the lease and begins the render, the loop, the upload thread, stop requests) still is.
#include <tbb/global_control.h>

namespace {
const tbb::global_control serial_tbb(tbb::global_control::max_allowed_parallelism, 1);
}  // namespace

extern "C" const char* __tsan_default_suppressions() {
  return "race:*Worker::head_start*lambda*\n";
}
