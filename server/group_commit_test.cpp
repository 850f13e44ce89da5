#include "server/group_commit.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <vector>

namespace tessera::server {
namespace {

// A flush the test opens one at a time: flush k returns only once the test has released k flushes.
struct HeldFlush {
  std::mutex mu;
  std::condition_variable cv;
  int started = 0, released = 0;
  std::vector<char> acked;  // acknowledgements in the order they ran
  void flush() {
    std::unique_lock lock(mu);
    const int me = ++started;
    cv.notify_all();
    cv.wait(lock, [&] { return released >= me; });
  }
  std::function<void()> ack(char name) {
    return [this, name] {
      std::lock_guard lock(mu);
      acked.push_back(name);
      cv.notify_all();
    };
  }
  void wait_started(int n) {
    std::unique_lock lock(mu);
    cv.wait(lock, [&] { return started >= n; });
  }
  void wait_acked(size_t n) {
    std::unique_lock lock(mu);
    cv.wait(lock, [&] { return acked.size() >= n; });
  }
  void release() {
    std::lock_guard lock(mu);
    ++released;
    cv.notify_all();
  }
  std::vector<char> acks() {
    std::lock_guard lock(mu);
    return acked;
  }
};

TEST(GroupCommit, AcknowledgesOnlyAfterAFlushAndSharesOneFlushForWhatArrivedMeanwhile) {
  HeldFlush h;
  GroupCommit gc([&] { h.flush(); });
  gc.after_flush(h.ack('a'));
  h.wait_started(1);  // a's flush runs
  gc.after_flush(h.ack('b'));
  gc.after_flush(h.ack('c'));
  EXPECT_TRUE(h.acks().empty()) << "nothing is acknowledged before its flush returned";
  h.release();
  h.wait_started(2);  // b and c: one flush for both, begun after a's
  EXPECT_EQ(h.acks(), std::vector<char>{'a'}) << "b and c arrived after a's flush began: it does not cover them";
  h.release();
  h.wait_acked(3);
  EXPECT_EQ(h.acks(), (std::vector<char>{'a', 'b', 'c'}));
  const GroupCommitStats st = gc.stats();
  EXPECT_EQ(st.flushes, 2u);
  EXPECT_EQ(st.acknowledged, 3u);
}

TEST(GroupCommit, FlushWaitsForAFlushThatBeganAfterIt) {
  HeldFlush h;
  GroupCommit gc([&] { h.flush(); });
  gc.after_flush(h.ack('a'));
  h.wait_started(1);
  bool returned = false;
  std::mutex mu;
  std::thread waiter([&] {
    gc.flush();  // arrives during a's flush: needs the next one
    std::lock_guard lock(mu);
    returned = true;
  });
  // a's flush ends only once the waiter's flush is queued behind it, so the scenario happens on every run.
  while (gc.stats().queued != 1) std::this_thread::yield();
  EXPECT_EQ(gc.stats().flushes, 0u) << "a's flush is still held";
  h.release();
  h.wait_started(2);
  {
    std::lock_guard lock(mu);
    EXPECT_FALSE(returned) << "returned on a flush that began before it was called";
  }
  h.release();
  waiter.join();
  EXPECT_TRUE(returned);
}

TEST(GroupCommit, DestructionServesWhatIsQueued) {
  std::vector<int> flushes;
  int acked = 0;
  {
    GroupCommit gc([&] { flushes.push_back(acked); });
    for (int i = 0; i < 5; ++i) gc.after_flush([&] { ++acked; });
  }
  EXPECT_EQ(acked, 5);
  EXPECT_FALSE(flushes.empty());
}

}  // namespace
}  // namespace tessera::server
