// A coordinator's state kept in memory only (serve --durability none): jobs, tiles, leases and workers live in the
// scheduler, done tiles' pixels and job records here, merged results in DIR/jobs/<id>/ as with the durable store.
#pragma once

#include "server/coordinator_store.h"

#include <map>
#include <mutex>
#include <optional>
#include <utility>

namespace tessera::server {

/// Nothing it holds survives the process: a restart finds no jobs, so opening it empties DIR/jobs/ and DIR/tmp/.
/// Thread-safe (one mutex).
class MemoryStore final : public CoordinatorStore {
 public:
  /// Makes DIR/jobs/ and DIR/tmp/ and removes whatever an earlier run left in them; throws StorageError, also when DIR
  /// holds a durable coordinator's database.
  explicit MemoryStore(const std::filesystem::path& dir);

  void apply(const SchedulerChanges& changes) override;
  /// An empty snapshot: nothing was kept from an earlier run.
  SchedulerSnapshot load() override;

  void save_record(const std::string& job, const nlohmann::json& record) override;
  std::optional<nlohmann::json> load_record(const std::string& job) override;
  std::vector<std::pair<int64_t, std::string>> tile_pixels(const std::string& job) override;
  void save_tile_state(const std::string& job, int64_t tile, uint32_t spp, std::string_view exr) override;
  std::optional<uint32_t> tile_state_spp(const std::string& job, int64_t tile) override;
  std::optional<std::pair<uint32_t, std::string>> tile_state(const std::string& job, int64_t tile) override;

  void append_audit(const protocol::AuditEntry& entry) override;
  protocol::AuditList audit(const protocol::AuditQuery& query) override;
  int64_t forget_audit(int64_t before_ms) override;
  size_t leftovers_removed() const override { return leftovers_removed_; }
  std::string where() const override { return "memory"; }

 private:
  size_t leftovers_removed_ = 0;
  std::mutex mu_;
  std::map<std::string, std::map<int64_t, std::string>> pixels_;  // job -> done tile -> float32 RGB rows (mu_)
  std::map<std::string, nlohmann::json> records_;                  // (mu_)
  std::map<std::pair<std::string, int64_t>, std::pair<uint32_t, std::string>> tile_states_;  // (mu_)
  std::map<int64_t, protocol::AuditEntry> audit_;  // by id (mu_)
};

}  // namespace tessera::server
