// Linked into the unit tests of the ThreadSanitizer build only (TESSERA_TSAN). Debian's oneTBB is not built with
// TSan: its task pool hands parallel_for tasks between threads through synchronisation TSan cannot see, so every
// parallel render is reported as a race inside TBB's headers. TBB is therefore held to the calling thread here
// (renders stay bitwise the same for any thread count), and TSan watches the threads the coordinator and the
// worker start themselves: the HTTP server's, the heartbeat thread, the tests' clients, and the locks between them.
#include <tbb/global_control.h>

namespace {
const tbb::global_control serial_tbb(tbb::global_control::max_allowed_parallelism, 1);
}  // namespace
