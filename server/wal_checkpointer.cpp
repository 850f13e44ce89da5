#include "server/wal_checkpointer.h"

#include "server/helper_thread.h"
#include "server/storage.h"

#include <sqlite3.h>
#include <spdlog/spdlog.h>

#include <sys/statvfs.h>

#include <algorithm>
#include <limits>

namespace tessera::server {

namespace {

// Bytes free on the file system of `folder` for an unprivileged process; the largest value when it cannot be asked.
uint64_t free_bytes(const std::filesystem::path& folder) {
  struct statvfs st {};
  if (::statvfs(folder.c_str(), &st) != 0) return std::numeric_limits<uint64_t>::max();
  return uint64_t(st.f_bavail) * uint64_t(st.f_frsize);
}

constexpr uint64_t kFrameBytes = 4096 + 24;  // a log frame: a page and its header

}  // namespace

WalCheckpointer::WalCheckpointer(const std::filesystem::path& file, bool flush, int threshold, WithWritesHeld held)
    : folder_(file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path()),
      threshold_(threshold),
      held_(std::move(held)) {
  if (sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
    const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    throw StorageError("cannot open " + file.string() + " for checkpoints: " + why);
  }
  sqlite3_busy_timeout(db_, 10'000);
  sqlite3_exec(db_, flush ? "PRAGMA synchronous=NORMAL" : "PRAGMA synchronous=OFF", nullptr, nullptr, nullptr);
  sqlite3_wal_autocheckpoint(db_, 0);  // this connection never writes; its checkpoints are the explicit ones below
  thread_ = std::thread([this] { loop(); });
}

WalCheckpointer::~WalCheckpointer() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
  sqlite3_close(db_);
}

bool WalCheckpointer::due_locked() const { return frames_ - copied_ >= threshold_; }

int WalCheckpointer::committed(int frames) {
  bool due = false;
  int written = 0;
  {
    std::lock_guard lock(mu_);
    if (frames < copied_) copied_ = 0;  // the log started over after a checkpoint that copied all of it
    written = frames >= frames_ ? frames - frames_ : frames;  // fewer than before: it started over
    frames_ = frames;
    due = due_locked();
  }
  if (due) cv_.notify_one();
  return written;
}

void WalCheckpointer::loop() {
  block_signals_in_helper_thread();
  std::unique_lock lock(mu_);
  for (;;) {
    cv_.wait(lock, [&] { return stopping_ || due_locked(); });
    if (stopping_) return;
    // The log starts over only after a checkpoint that copied all of it; while commits arrive during every checkpoint
    // it keeps growing, so once it is long, checkpoints catch up with it until little is left, and one copies the
    // rest with commits held off (as short as that is: a few frames and their flush).
    // So too when the disk has less room left than the log holds: a log that kept growing would fill it, and then
    // no checkpoint could copy it (the database file grows with it) until space were freed.
    const bool finish = frames_ >= kFinishFactor * threshold_ || free_bytes(folder_) < uint64_t(frames_) * kFrameBytes;
    lock.unlock();
    int copied = checkpoint();
    if (copied < 0) {  // failed (the disk is full, say): not again before another threshold of commits
      lock.lock();
      copied_ = frames_;
      continue;
    }
    if (finish) {
      for (int pass = 0; pass < kCatchUpPasses; ++pass) {
        lock.lock();
        const int left = frames_ - copied;
        lock.unlock();
        if (left <= threshold_ / 8) break;
        copied = std::max(0, checkpoint());
      }
      held_([&] { copied = std::max(0, checkpoint()); });
    }
    lock.lock();
    copied_ = frames_ >= copied ? copied : 0;  // a commit since may have seen the log start over
  }
}

bool WalCheckpointer::truncate(std::string* why) {
  std::lock_guard lock(checkpoint_mu_);
  int log = 0, copied = 0;
  const int rc = sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_TRUNCATE, &log, &copied);
  checkpoints_.fetch_add(1);
  if (rc == SQLITE_OK) return true;
  if (why) *why = sqlite3_errmsg(db_);
  else
    spdlog::warn("checkpoint of the database to cut its log failed: {} (the log keeps its size until a later one)",
                 sqlite3_errmsg(db_));
  return false;
}

int WalCheckpointer::checkpoint() {
  std::lock_guard lock(checkpoint_mu_);
  int log = 0, copied = 0;
  const int rc = sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_PASSIVE, &log, &copied);
  checkpoints_.fetch_add(1);
  if (rc != SQLITE_OK && rc != SQLITE_BUSY) {
    spdlog::warn("checkpoint of the database failed: {} (tried again after later commits)", sqlite3_errmsg(db_));
    return -1;
  }
  return std::max(0, copied);
}

}  // namespace tessera::server
