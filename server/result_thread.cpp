#include "server/result_thread.h"

#include "server/helper_thread.h"

#include <boost/asio/post.hpp>
#include <spdlog/spdlog.h>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace tessera::server {

namespace {

// Once per thread: signals blocked (a helper thread) and the nice value raised by ResultThread::kNice (on Linux a
// thread's own; best effort: a failure leaves the thread at the process's priority).
void prepare_thread() {
  thread_local bool prepared = false;
  if (prepared) return;
  prepared = true;
  block_signals_in_helper_thread();
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  errno = 0;
  const int nice = ::getpriority(PRIO_PROCESS, tid);
  if (errno == 0 && ::setpriority(PRIO_PROCESS, tid, nice + ResultThread::kNice) != 0)
    spdlog::debug("results' thread keeps its priority: {}", std::strerror(errno));
}

}  // namespace

ResultThread::~ResultThread() {
  pool_.stop();
  pool_.join();
}

void ResultThread::post(std::function<void()> work) {
  boost::asio::post(pool_, [this, work = std::move(work)] {
    prepare_thread();
    arena_.execute(work);
  });
}

void ResultThread::join() { pool_.join(); }

}  // namespace tessera::server
