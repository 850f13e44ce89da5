// Where a coordinator keeps its state: the scheduler's rows and the jobs' records and outputs, on the disk
// (DurableStore) or, for a coordinator that dies with the command that started it, in memory (MemoryStore).
#pragma once

#include "server/audit_store.h"
#include "server/latency_histogram.h"
#include "server/scheduler_store.h"
#include "server/storage.h"

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace tessera::server {

/// What a store's disk has cost so far (GET /metrics: tessera_store_*).
struct StoreStats {
  LatencyHistogram flushes;  ///< Each flush: the pixel files written since the last, then the log.
  uint64_t log_pages = 0;    ///< Database pages written to the write-ahead log.
};

/// The scheduler's store, the job store and the audit trail of one coordinator. The job outputs are files either way: merged results
/// in DIR/jobs/<id>/result.exr, written as the durability asks, and scratch files in DIR/tmp/.
class CoordinatorStore : public SchedulerStore, public JobStore, public AuditStore {
 public:
  /// Outputs under `dir` (DIR/jobs/ and DIR/tmp/ are made here), results written with `durability`'s flush.
  CoordinatorStore(const std::filesystem::path& dir, Durability durability);

  /// How many leftovers of an earlier run opening it removed.
  virtual size_t leftovers_removed() const = 0;
  /// Where the state is kept, for log lines (a database file, or "memory").
  virtual std::string where() const = 0;
  /// After a write failed for want of space (DiskFullError): makes what room the store can for the next writes (a
  /// database copies its write-ahead log into its file and cuts the log to nothing). True when writes may be tried
  /// again; false while the store could not do it (the disk is still too full).
  virtual bool make_room() { return true; }
  /// What its disk has cost so far; none for a store in memory.
  virtual std::optional<StoreStats> stats() const { return std::nullopt; }

  std::filesystem::path result_path(const std::string& job) final;
  void write_result(const std::string& job, const std::function<void(const std::filesystem::path&)>& write) final;
  std::filesystem::path scratch_dir() final { return scratch_; }
  void remove_outputs(const std::string& job) final;
  std::vector<std::string> jobs_with_outputs() final;

 protected:
  const std::filesystem::path jobs_dir_, scratch_;
  const Durability durability_;

 private:
  std::filesystem::path dir_;
};

/// Where the coordinator with data folder `dir` keeps a job's merged result: DIR/jobs/<job>/result.exr.
std::filesystem::path job_result_file(const std::filesystem::path& dir, const std::string& job);

/// The store under `dir` for `durability`: a DurableStore, or a MemoryStore for Durability::none. Throws StorageError.
std::unique_ptr<CoordinatorStore> open_coordinator_store(const std::filesystem::path& dir, Durability durability);

}  // namespace tessera::server
