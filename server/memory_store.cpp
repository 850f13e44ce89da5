#include "server/memory_store.h"

#include "core/util/file_io.h"
#include "server/database.h"

namespace tessera::server {

namespace fs = std::filesystem;

MemoryStore::MemoryStore(const fs::path& dir) : CoordinatorStore(dir, Durability::none) {
  // Opening would empty DIR/jobs/: never in a folder whose jobs a durable coordinator still knows.
  if (std::error_code ec; fs::exists(dir / DurableStore::kFileName, ec) || ec)
    throw StorageError(dir.string() + " holds a durable coordinator's database (" + DurableStore::kFileName +
                       "): a coordinator keeping its state in memory would throw that coordinator's results away; give "
                       "it a folder of its own");
  leftovers_removed_ = remove_leftovers(scratch_, true) + remove_leftovers(jobs_dir_, true);
}

void MemoryStore::apply(const SchedulerChanges& c) {
  std::lock_guard lock(mu_);
  for (const TileRow& r : c.tiles)
    if (r.pixels) pixels_[r.job][r.index] = std::string(*r.pixels);
  for (const std::string& job : c.purged_jobs) {
    pixels_.erase(job);
    records_.erase(job);
    tile_states_.erase(tile_states_.lower_bound({job, INT64_MIN}), tile_states_.upper_bound({job, INT64_MAX}));
  }
}

SchedulerSnapshot MemoryStore::load() { return {}; }

void MemoryStore::save_record(const std::string& job, const nlohmann::json& record) {
  std::lock_guard lock(mu_);
  records_[job] = record;
}

std::optional<nlohmann::json> MemoryStore::load_record(const std::string& job) {
  std::lock_guard lock(mu_);
  const auto it = records_.find(job);
  if (it == records_.end()) return std::nullopt;
  return it->second;
}

std::vector<std::pair<int64_t, std::string>> MemoryStore::tile_pixels(const std::string& job) {
  std::lock_guard lock(mu_);
  std::vector<std::pair<int64_t, std::string>> out;
  if (const auto it = pixels_.find(job); it != pixels_.end())
    for (const auto& [index, bytes] : it->second) out.emplace_back(index, bytes);
  return out;
}

void MemoryStore::save_tile_state(const std::string& job, int64_t tile, uint32_t spp, std::string_view exr) {
  std::lock_guard lock(mu_);
  tile_states_[{job, tile}] = {spp, std::string(exr)};
}

std::optional<uint32_t> MemoryStore::tile_state_spp(const std::string& job, int64_t tile) {
  std::lock_guard lock(mu_);
  const auto it = tile_states_.find({job, tile});
  if (it == tile_states_.end()) return std::nullopt;
  return it->second.first;
}

std::optional<std::pair<uint32_t, std::string>> MemoryStore::tile_state(const std::string& job, int64_t tile) {
  std::lock_guard lock(mu_);
  const auto it = tile_states_.find({job, tile});
  if (it == tile_states_.end()) return std::nullopt;
  return it->second;
}

void MemoryStore::append_audit(const protocol::AuditEntry& entry) {
  std::lock_guard lock(mu_);
  protocol::AuditEntry e = entry;
  e.id = audit_.empty() ? 1 : audit_.rbegin()->first + 1;
  audit_.emplace(e.id, std::move(e));
}

protocol::AuditList MemoryStore::audit(const protocol::AuditQuery& q) {
  std::lock_guard lock(mu_);
  protocol::AuditList out;
  auto it = q.before ? audit_.lower_bound(*q.before) : audit_.end();
  while (it != audit_.begin()) {
    --it;
    if (!q.user.empty() && it->second.user != q.user) continue;
    if (out.entries.size() == q.limit) {
      out.next = out.entries.back().id;
      break;
    }
    out.entries.push_back(it->second);
  }
  return out;
}

int64_t MemoryStore::forget_audit(int64_t before_ms) {
  std::lock_guard lock(mu_);
  int64_t n = 0;
  for (auto it = audit_.begin(); it != audit_.end();)
    if (it->second.at_ms < before_ms) {
      it = audit_.erase(it);
      ++n;
    } else {
      ++it;
    }
  return n;
}

}  // namespace tessera::server
