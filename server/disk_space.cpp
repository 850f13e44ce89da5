#include "server/disk_space.h"

#include <spdlog/spdlog.h>

#include <sys/statvfs.h>

#include <limits>

namespace tessera::server {

namespace {

std::string mib(uint64_t bytes) {
  return fmt::format("{:.1f} MiB", double(bytes) / double(uint64_t(1) << 20));
}

}  // namespace

DiskSpace::DiskSpace(std::filesystem::path dir, uint64_t min_free) : dir_(std::move(dir)), min_free_(min_free) {}

uint64_t DiskSpace::free_bytes() const {
  struct statvfs st {};
  if (::statvfs(dir_.c_str(), &st) != 0) return std::numeric_limits<uint64_t>::max();
  return uint64_t(st.f_bavail) * uint64_t(st.f_frsize);
}

protocol::DiskState DiskSpace::state() const {
  if (full()) return protocol::DiskState::full;
  return free_bytes() < min_free_ ? protocol::DiskState::low : protocol::DiskState::ok;
}

void DiskSpace::note_full(const std::string& what) {
  std::lock_guard lock(mu_);
  if (full_.exchange(true)) return;
  spdlog::error("the disk of {} is full ({}); reads go on, new work, leases and tile uploads are refused (507) until "
                "space is freed, and the coordinator tries its writes again every second",
                dir_.string(), what);
}

void DiskSpace::note_room() {
  std::lock_guard lock(mu_);
  if (!full_.exchange(false)) return;
  spdlog::info("the disk of {} has room again ({} free): accepting work", dir_.string(), mib(free_bytes()));
}

void DiskSpace::require(protocol::Room room) const {
  if (room == protocol::Room::any) return;
  if (full())
    throw protocol::ApiError(507, "the coordinator's disk is full: it takes no new work, leases or tile uploads until "
                                  "space is freed on it; try again later");
  if (room != protocol::Room::above_floor || min_free_ == 0) return;
  if (const uint64_t free = free_bytes(); free < min_free_)
    throw protocol::ApiError(507, "the coordinator's disk has " + mib(free) + " free, below its floor of " +
                                      mib(min_free_) +
                                      " (serve --min-free-disk): it takes no submissions or blob uploads until space "
                                      "is freed on it; try again later");
}

protocol::ApiError DiskSpace::refusal(const std::string& why) const {
  return protocol::ApiError(507, "the coordinator's disk is full (" + why + "): try again once space is freed on it");
}

}  // namespace tessera::server
