// The free space of the coordinator's data folder: the floor below which new work is refused, and the disk-full
// condition that a write failing for want of space sets and a write succeeding again clears (docs/operations.md,
// "Disk full").
#pragma once

#include "protocol/errors.h"
#include "protocol/messages.h"
#include "protocol/routes.h"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>

namespace tessera::server {

/// The free space of one file system and whether the coordinator found it full. Thread-safe.
class DiskSpace {
 public:
  /// The file system holding `dir`; submissions and blob uploads are refused while less than `min_free` bytes are
  /// free on it (0: only when it is full).
  DiskSpace(std::filesystem::path dir, uint64_t min_free);

  /// Bytes free on it for an unprivileged process (statvfs); the largest value when it cannot be asked.
  uint64_t free_bytes() const;
  /// The floor it was made with.
  uint64_t min_free() const { return min_free_; }
  /// True from note_full() until note_room().
  bool full() const { return full_.load(); }
  /// Full, low (below the floor) or ok, now.
  protocol::DiskState state() const;

  /// A write failed for want of space (`what` names it): from now on requests of Room::not_full and
  /// Room::above_floor are refused. The first of a spell is logged.
  void note_full(const std::string& what);
  /// Writes succeed again: the end of a spell is logged.
  void note_room();

  /// Throws the 507 refusal when a request needing `room` may not be tried now.
  void require(protocol::Room room) const;
  /// The 507 refusal of a request whose write failed for want of space (`why`: the error).
  protocol::ApiError refusal(const std::string& why) const;

 private:
  const std::filesystem::path dir_;
  const uint64_t min_free_;
  std::atomic<bool> full_{false};
  std::mutex mu_;  // orders note_full and note_room, so that each spell is logged once at each end
};

}  // namespace tessera::server
