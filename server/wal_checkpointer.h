// Checkpoints off the commit path: the write-ahead log is copied into the database file by a thread and a connection
// of its own, so that no commit (and no scheduler lock held around one) pays for a checkpoint.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

struct sqlite3;

namespace tessera::server {

/// Runs SQLite's checkpoints of one WAL database (whose connections have their automatic checkpoint turned off) on a
/// thread of its own. Thread-safe.
class WalCheckpointer {
 public:
  /// Runs code while the store lets no commit happen (its lock), so a checkpoint can finish the log and let it start
  /// over.
  using WithWritesHeld = std::function<void(const std::function<void()>&)>;

  /// Checkpoints `file` once the log has `threshold` frames (pages) after a commit; with `flush`, each completed
  /// checkpoint flushes the database file (SQLite's synchronous=NORMAL), else nothing is flushed. When the log has
  /// grown past 32 x `threshold` because commits never paused long enough for a checkpoint to finish it, or holds
  /// more than the disk has free, checkpoints catch up until an eighth of `threshold` is left, and one checkpoint
  /// copies that inside `held`. Throws StorageError when the file cannot be opened.
  WalCheckpointer(const std::filesystem::path& file, bool flush, int threshold, WithWritesHeld held);
  /// Waits for a checkpoint in progress, then closes its connection.
  ~WalCheckpointer();
  WalCheckpointer(const WalCheckpointer&) = delete;
  WalCheckpointer& operator=(const WalCheckpointer&) = delete;

  /// After a commit (from the committing thread, quickly): the log now holds `frames` frames. Returns how many of them
  /// the commit wrote (all of them when the log started over).
  int committed(int frames);
  /// Copies the whole log into the database file and cuts the log to zero bytes, after any checkpoint in progress;
  /// the caller holds off commits (SQLite waits for a writer for up to 10 s). False when SQLite could not finish it,
  /// with SQLite's reason in `why` when given, else logged as a warning.
  bool truncate(std::string* why = nullptr);
  /// Checkpoints run so far.
  uint64_t checkpoints() const { return checkpoints_.load(); }

 private:
  static constexpr int kFinishFactor = 32;  // log frames (x threshold) after which it is finished and starts over
  static constexpr int kCatchUpPasses = 4;   // checkpoints without holding commits before the held one
  void loop();
  int checkpoint();        // one passive checkpoint; the frames of the log it has copied, -1 when it failed
  bool due_locked() const;  // enough frames beyond those already copied

  const std::filesystem::path folder_;  // where the database and its log are
  sqlite3* db_ = nullptr;
  std::mutex checkpoint_mu_;  // one checkpoint on db_ at a time (the thread's, or truncate()'s)
  const int threshold_;
  WithWritesHeld held_;
  std::mutex mu_;
  std::condition_variable cv_;
  int frames_ = 0;  // frames in the log after the last commit
  int copied_ = 0;  // frames of the log copied by the checkpoints since it last started over
  bool stopping_ = false;
  std::atomic<uint64_t> checkpoints_{0};
  std::thread thread_;  // last: starts after every other member is ready
};

}  // namespace tessera::server
