// The durable store and the scheduler over a file system that fills up: a real 1 MiB tmpfs, mounted in a child
// process with a mount namespace of its own (skipped, saying why, where the kernel refuses one).
#include "server/database.h"

#include "core/util/file_io.h"
#include "server/scheduler.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sched.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

constexpr int kSkip = 77;  // the child's exit status when it cannot have a mount namespace

// In the child: a mount namespace of its own (as root, or as root of a new user namespace), so that a tmpfs mounted
// there is seen by nobody else and goes with the child. False when the kernel refuses both.
bool own_mount_namespace() {
  if (::unshare(CLONE_NEWNS) == 0) return ::mount("none", "/", nullptr, MS_REC | MS_PRIVATE, nullptr) == 0;
  const uid_t uid = ::getuid();
  const gid_t gid = ::getgid();
  if (::unshare(CLONE_NEWUSER | CLONE_NEWNS) != 0) return false;
  const auto write = [](const char* file, const std::string& text) {
    std::ofstream f(file);
    f << text;
    return bool(f.flush());
  };
  return write("/proc/self/setgroups", "deny") && write("/proc/self/uid_map", "0 " + std::to_string(uid) + " 1") &&
         write("/proc/self/gid_map", "0 " + std::to_string(gid) + " 1") &&
         ::mount("none", "/", nullptr, MS_REC | MS_PRIVATE, nullptr) == 0;
}

// Runs `body` in a child process with `dir` a tmpfs of `size` (mount's size= text) that `resize` can change; the
// child's failures are printed and make it exit 1. Returns the child's exit status (kSkip: no namespace).
template <class Body>
int on_small_disk(const fs::path& dir, const char* size, Body body) {
  fs::create_directories(dir);
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (!own_mount_namespace()) {
      std::fprintf(stderr, "cannot make a private mount namespace here: %s\n", std::strerror(errno));
      std::_Exit(kSkip);
    }
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, (std::string("size=") + size).c_str()) != 0) {
      std::fprintf(stderr, "cannot mount a tmpfs on %s: %s\n", dir.c_str(), std::strerror(errno));
      std::_Exit(kSkip);
    }
    const auto resize = [&dir](const char* to) {
      return ::mount("tmpfs", dir.c_str(), "tmpfs", MS_REMOUNT, (std::string("size=") + to).c_str()) == 0;
    };
    int status = 0;
    try {
      status = body(resize);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "unexpected exception: %s\n", e.what());
      status = 1;
    }
    std::fflush(nullptr);
    std::_Exit(status);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  std::error_code ec;
  fs::remove_all(dir, ec);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

#define CHILD_CHECK(condition)                                              \
  do {                                                                      \
    if (!(condition)) {                                                     \
      std::fprintf(stderr, "%s:%d: failed: %s\n", __FILE__, __LINE__, #condition); \
      return 1;                                                             \
    }                                                                       \
  } while (0)

JobParams params(int tiles) {
  JobParams p;
  p.name = "n";
  p.width = 64 * tiles;
  p.height = 64;
  p.tile_size = 64;
  p.spp = 1;
  p.scene_hash = "hash";
  return p;
}

TEST(DiskFullTest, TheStoreRefusesWritesUntilItsLogIsCutThenTakesTheWaitingChanges) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-disk-full-test-" + random_hex(6));
  const int status = on_small_disk(dir, "1m", [&](const auto& resize) {
    int64_t now = 1'000'000;
    DurableStore store(dir);
    Scheduler sched(SchedulerConfig{10'000, 3, 2, "d"}, [&] { return now; }, store);
    const std::string worker = sched.register_worker("w").id;
    const std::string first = sched.add_job(params(2));
    // Tiles of 64 x 64 pixels (48 KiB each) until the disk has no room for the next.
    const std::string big = sched.add_job(params(64));
    const std::string pixels(size_t(64) * 64 * 12, '\x01');
    int stored = 0;
    bool full = false;
    while (!full) {
      // The disk may fill on a lease's grant (a small write) as well as on a tile's pixels: either is refused whole.
      AcquireResult a;
      try {
        a = sched.acquire(worker);
      } catch (const DiskFullError&) {
        full = true;
        break;
      }
      CHILD_CHECK(a.status == AcquireResult::granted);
      CHILD_CHECK(sched.claim_result(a.lease.id).status == ResultClaim::proceed);
      try {
        sched.finish_result(a.lease.id, 1, pixels);
        ++stored;
      } catch (const DiskFullError&) {
        full = true;
        // The upload is handed back, as the coordinator does: the store cannot take that either, and it need not.
        sched.abandon_result(a.lease.id);
      }
      CHILD_CHECK(stored < 64);
    }
    CHILD_CHECK(stored > 0);
    // The pixel files hold the stored tiles' bytes and nothing of the refused one.
    const auto pixel_bytes = [&] {
      uintmax_t n = 0;
      for (const auto& f : fs::directory_iterator(dir / DurableStore::kPixelsDir)) n += fs::file_size(f.path());
      return n;
    };
    CHILD_CHECK(pixel_bytes() == uintmax_t(stored) * pixels.size());
    // Views still answer, with nothing lost or invented (the first job's two tiles were leased first).
    const auto done = [&] { return sched.job(first)->tiles.done + sched.job(big)->tiles.done; };
    CHILD_CHECK(done() == stored);
    CHILD_CHECK(sched.jobs().size() == 2);
    CHILD_CHECK(sched.tiles(first).has_value());
    CHILD_CHECK(sched.heartbeat("l-nope").status == HeartbeatResult::unknown);
    // Every write fails at once until the log is cut; a job the store did not take does not exist.
    bool refused = false;
    try {
      sched.add_job(params(1));
    } catch (const DiskFullError&) {
      refused = true;
    }
    CHILD_CHECK(refused);
    CHILD_CHECK(sched.jobs().size() == 2);
    // Space returns: the log is copied into the database and cut, and the changes that waited are stored.
    CHILD_CHECK(resize("8m"));
    CHILD_CHECK(store.make_room());
    CHILD_CHECK(fs::file_size(dir / (std::string(DurableStore::kFileName) + "-wal")) == 0);
    sched.store_pending();
    const AcquireResult again = sched.acquire(worker);
    CHILD_CHECK(again.status == AcquireResult::granted);
    CHILD_CHECK(sched.claim_result(again.lease.id).status == ResultClaim::proceed);
    sched.finish_result(again.lease.id, 1, pixels);
    const std::string later = sched.add_job(params(1));
    CHILD_CHECK(done() == stored + 1);
    CHILD_CHECK(store.tile_pixels(first).size() + store.tile_pixels(big).size() == size_t(stored) + 1);
    CHILD_CHECK(pixel_bytes() == uintmax_t(stored + 1) * pixels.size());
    // And all of it is what a restart finds.
    SchedulerSnapshot snap = store.load();
    CHILD_CHECK(snap.jobs.size() == 3);
    return 0;
  });
  if (status == kSkip) GTEST_SKIP() << "no private mount namespace here (see the test's output)";
  EXPECT_EQ(status, 0);
}

TEST(DiskFullTest, AFullDiskIsADiskFullErrorAndOtherFailuresAreNot) {
  EXPECT_TRUE(is_disk_full(DiskFullError("x")));
  EXPECT_TRUE(is_disk_full(StorageError("x", ENOSPC)));
  EXPECT_TRUE(is_disk_full(StorageError("x", EDQUOT)));
  EXPECT_FALSE(is_disk_full(StorageError("x", EACCES)));
  EXPECT_FALSE(is_disk_full(StorageError("x")));
  EXPECT_FALSE(is_disk_full(std::runtime_error("No space left on device")));
  const fs::path dir = fs::temp_directory_path() / ("tessera-disk-full-test-" + random_hex(6));
  const int status = on_small_disk(dir, "64k", [&](const auto&) {
    try {
      write_file_atomic(dir / "f", std::string(size_t(1) << 20, 'x'));
    } catch (const FileError& e) {
      CHILD_CHECK(is_disk_full(e));
      CHILD_CHECK(fs::is_empty(dir));  // no temp file left behind
      return 0;
    }
    return 1;
  });
  if (status == kSkip) GTEST_SKIP() << "no private mount namespace here (see the test's output)";
  EXPECT_EQ(status, 0);
}

}  // namespace
}  // namespace tessera::server
