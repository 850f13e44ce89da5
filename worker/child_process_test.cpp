#include "tests/support/test_files.h"
#include "worker/child_process.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <future>
#include <stdexcept>
#include <thread>

namespace tessera::worker {
namespace {

using namespace std::chrono_literals;

class ChildProcessTest : public testing::TempDirTest {};

// Waits up to 10 s for the child to exit and returns its exit code (-1 when it was killed or did not exit).
int exit_code(ChildProcess& c) {
  for (int i = 0; i < 1000 && !child_exited(c); ++i) std::this_thread::sleep_for(10ms);
  if (!c.reaped) {
    std::vector<ChildProcess> left{c};
    kill_children(left);
    return -1;
  }
  return WIFEXITED(c.exit_status) ? WEXITSTATUS(c.exit_status) : -1;
}

// A process run under ThreadSanitizer has the sanitizer's thread besides its own, so there fork_child must refuse.
TEST_F(ChildProcessTest, ForkChildRunsTheBodyInACopyAndExitsWithItsResult) {
  const auto log = file("child.log");
  int here = 41;
  if (!single_threaded()) {
    EXPECT_THROW(fork_child([] { return 0; }, "copy", log), std::logic_error);
    return;
  }
  ChildProcess c = fork_child(
      [&here] {
        ++here;  // the child's copy only
        std::printf("the copy sees %d\n", here);
        return 7;
      },
      "copy", log, -1, "tessera-test");
  EXPECT_EQ(exit_code(c), 7);
  EXPECT_EQ(here, 41);
  std::ifstream in(log);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "the copy sees 42");
}

TEST_F(ChildProcessTest, ForkChildKeepsOnlyTheDescriptorItIsGiven) {
  int kept[2], other[2];
  ASSERT_EQ(::pipe2(kept, O_CLOEXEC), 0);
  ASSERT_EQ(::pipe2(other, O_CLOEXEC), 0);
  if (!single_threaded()) {
    EXPECT_THROW(fork_child([] { return 0; }, "copy", file("child.log"), kept[0]), std::logic_error);
  } else {
    ChildProcess c = fork_child(
        [&] {
          const bool kept_open = ::fcntl(kept[0], F_GETFD) >= 0;
          const bool others_closed = ::fcntl(other[0], F_GETFD) < 0 && ::fcntl(other[1], F_GETFD) < 0 &&
                                     ::fcntl(kept[1], F_GETFD) < 0;
          char byte = 0;
          const bool reads = kept_open && ::read(kept[0], &byte, 1) == 1 && byte == 'x';
          return kept_open && others_closed && reads ? 0 : 1;
        },
        "copy", file("child.log"), kept[0]);
    ASSERT_EQ(::write(kept[1], "x", 1), 1);
    EXPECT_EQ(exit_code(c), 0) << "the child saw descriptors it should not have, or lost the one it was given";
  }
  for (const int fd : {kept[0], kept[1], other[0], other[1]}) ::close(fd);
}

TEST_F(ChildProcessTest, ForkChildRefusesWhileAnotherThreadRuns) {
  std::promise<void> done;
  std::thread other([f = done.get_future()]() mutable { f.wait(); });
  EXPECT_FALSE(single_threaded());
  EXPECT_THROW(fork_child([] { return 0; }, "copy", file("child.log")), std::logic_error);
  done.set_value();
  other.join();
}

TEST_F(ChildProcessTest, ABodyThatThrowsExitsWithOne) {
  const auto body = []() -> int { throw std::runtime_error("no"); };
  if (!single_threaded()) {
    EXPECT_THROW(fork_child(body, "copy", file("child.log")), std::logic_error);
    return;
  }
  ChildProcess c = fork_child(body, "copy", file("child.log"));
  EXPECT_EQ(exit_code(c), 1);
}

}  // namespace
}  // namespace tessera::worker
