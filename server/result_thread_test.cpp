// The results' thread: work runs in order on one thread, at the lowered priority, with parallel algorithms confined
// to it, and join() waits for what was queued.
#include "server/result_thread.h"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

namespace tessera::server {
namespace {

TEST(ResultThread, RunsWorkInOrderOnOneThreadAndJoinWaitsForIt) {
  std::vector<int> order;
  std::set<std::thread::id> threads;
  {
    ResultThread r;
    for (int i = 0; i < 20; ++i)
      r.post([&, i] {
        order.push_back(i);  // one thread: no lock needed, which TSan checks
        threads.insert(std::this_thread::get_id());
      });
    r.join();
    ASSERT_EQ(order.size(), 20u);
  }
  for (int i = 0; i < 20; ++i) EXPECT_EQ(order[size_t(i)], i);
  EXPECT_EQ(threads.size(), 1u);
  EXPECT_EQ(threads.count(std::this_thread::get_id()), 0u);
}

TEST(ResultThread, ParallelLoopsStayOnItsThreadAtTheLoweredPriority) {
  errno = 0;
  const int process_nice = ::getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)));
  ASSERT_EQ(errno, 0);
  int nice = 0, concurrency = 0;
  std::mutex mu;
  std::set<std::thread::id> loop_threads;
  std::thread::id own;
  ResultThread r;
  r.post([&] {
    nice = ::getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)));
    concurrency = tbb::this_task_arena::max_concurrency();
    own = std::this_thread::get_id();
    tbb::parallel_for(0, 10000, [&](int) {
      std::lock_guard lock(mu);
      loop_threads.insert(std::this_thread::get_id());
    });
  });
  r.join();
  EXPECT_EQ(concurrency, 1);
  EXPECT_EQ(loop_threads, std::set<std::thread::id>{own});
  // Raising a nice value needs no privilege; at the ceiling (19) it stays there.
  EXPECT_EQ(nice, std::min(19, process_nice + ResultThread::kNice));
}

}  // namespace
}  // namespace tessera::server
