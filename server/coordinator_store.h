// Where a coordinator keeps its state: the scheduler's rows and the jobs' records and outputs, on the disk
// (DurableStore) or, for a coordinator that dies with the command that started it, in memory (MemoryStore).
#pragma once

#include "server/scheduler.h"
#include "server/storage.h"

#include <filesystem>
#include <memory>
#include <string>

namespace tessera::server {

/// The scheduler's store and the job store of one coordinator.
class CoordinatorStore : public SchedulerStore, public JobStore {
 public:
  /// How many leftovers of an earlier run opening it removed.
  virtual size_t leftovers_removed() const = 0;
  /// Where the state is kept, for log lines (a database file, or "memory").
  virtual std::string where() const = 0;
};

/// The store under `dir` for `durability`: a DurableStore, or a MemoryStore for Durability::none. Throws StorageError.
std::unique_ptr<CoordinatorStore> open_coordinator_store(const std::filesystem::path& dir, Durability durability);

}  // namespace tessera::server
