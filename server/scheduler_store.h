// The rows the scheduler's state is stored as, the batch of them one operation changes, and the store that takes
// each batch in one transaction (server/database.h in SQLite, server/memory_store.h in memory).
#pragma once

#include "server/outbox.h"
#include "server/scheduler_types.h"

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// A job as the store keeps it: its snapshot (tile counts are derived from the tiles) and its failure bookkeeping.
struct JobRow {
  JobStatus status;                                       ///< Params, state, times, error, rays, workers.
  uint64_t seq = 0;                                       ///< Submission order (ties in the queue).
  std::map<std::string, int> worker_failures;             ///< Worker -> failures on this job.
  std::map<std::string, std::string> worker_last_error;   ///< Worker -> its latest error on this job.
};

/// A worker that rendered a tile of a job, `index` in the order of their first tiles (status.workers). A job's list
/// grows a row at a time, so a change never rewrites a list as long as the farm.
struct JobWorkerRow {
  std::string job;     ///< Job id.
  int64_t index = 0;   ///< Position in the job's list.
  std::string worker;  ///< Worker id.
};

/// A tile as the store keeps it; `pixels` is set only in the change that makes it done.
struct TileRow {
  std::string job;                                ///< Job id.
  int64_t index = 0;                              ///< Tile number.
  TileState state = TileState::pending;           ///< Where it is.
  std::string lease;                              ///< The live or claiming lease.
  std::map<std::string, std::string> failures;    ///< Worker -> last error text on this tile.
  std::optional<std::string_view> pixels;         ///< The validated tile's bytes (float32 RGB rows), when it became done.
  std::map<std::string, std::vector<std::string>> logs;  ///< Worker -> log lines sent with its last failure.
  int64_t attempts = 0;                           ///< Leases granted for it.
  int64_t render_ms = -1;                         ///< Lease grant to upload of the accepted result (-1: none yet).
  uint64_t rays = 0;                              ///< Rays of the accepted result's lease.
  std::string rendered_by;                        ///< The worker whose result was accepted ("" until done).
  std::vector<std::string> log{};                 ///< Done: the log lines sent with the accepted upload.
  bool log_not_kept = false;                      ///< Done: a log came, but the job's tile logs were full.
};

/// A lease as the store keeps it.
struct LeaseRow {
  Lease lease;                             ///< What was granted (window, spp, seed are derived from the job on load).
  LeaseState state = LeaseState::live;     ///< Where it is.
  int64_t granted_ms = 0;                  ///< When it was granted (the tile timeout counts from here).
};

/// A registered worker.
struct WorkerRow {
  std::string id;        ///< Worker id.
  std::string name;      ///< Its self-reported name.
  bool drained = false;  ///< An operator drained it (no new leases until undrained).
  std::string secret_hash{};  ///< SHA-256 of its secret, hex ("": registered by a build without secrets).
  std::vector<std::string> tags{};  ///< What it offers, as it registered.
};

/// Counters and the id sequence, kept so a restarted coordinator continues them.
struct CounterRow {
  uint64_t next_seq = 1;        ///< Next number in generated ids.
  uint64_t tiles_rendered = 0;  ///< Tiles merged.
  uint64_t lease_expiries = 0;  ///< Leases that expired.
  uint64_t rays = 0;            ///< Rays reported by workers.
  /// Field-wise equality (to skip writing unchanged counters).
  bool operator==(const CounterRow&) const = default;
};

/// What one scheduler operation changed: rows to insert or replace, in one batch.
struct SchedulerChanges {
  std::vector<JobRow> jobs;        ///< Changed jobs (their status.workers is empty: see job_workers).
  std::vector<JobWorkerRow> job_workers;  ///< Workers added to jobs' lists.
  std::vector<TileRow> tiles;      ///< Changed tiles.
  std::vector<LeaseRow> leases;    ///< Changed leases.
  std::vector<WorkerRow> workers;  ///< New workers, and workers drained or undrained.
  std::vector<std::string> forgotten_workers;  ///< Workers whose rows go (offline past their retention).
  std::vector<std::string> purged_jobs;  ///< Jobs whose every row (job, tiles, leases, record) goes.
  std::vector<OutboxRow> outbox;   ///< Webhook events the changes caused (server/outbox.h).
  CounterRow counters;             ///< Counters after the operation.
  /// True when nothing but the counters changed.
  bool empty() const {
    return jobs.empty() && job_workers.empty() && tiles.empty() && leases.empty() && workers.empty() &&
           forgotten_workers.empty() && purged_jobs.empty() && outbox.empty();
  }
};

/// Everything a store holds, for a scheduler starting over it (tile pixels are not loaded).
struct SchedulerSnapshot {
  std::vector<JobRow> jobs;        ///< Every job.
  std::vector<TileRow> tiles;      ///< Every tile of every job (pixels unset).
  std::vector<LeaseRow> leases;    ///< Every lease ever granted.
  std::vector<WorkerRow> workers;  ///< Every registered worker.
  CounterRow counters;             ///< Counters and id sequence.
};

/// Durable home of the scheduler's state. apply() is all-or-nothing: after it returns, the changes survive a crash of
/// the process (when it throws, none of them were stored); after a later sync() returns they survive a power cut too.
class SchedulerStore {
 public:
  virtual ~SchedulerStore() = default;
  /// Stores one operation's changes atomically; throws StorageError (or another std::exception) on failure.
  virtual void apply(const SchedulerChanges& changes) = 0;
  /// Everything stored so far.
  virtual SchedulerSnapshot load() = 0;
  /// Waits until every change applied so far is on the disk. The scheduler calls it without holding its lock after
  /// operations that acknowledge something (a submission, a done tile, a job's end), so concurrent callers share one
  /// disk flush and lease grants never wait for one.
  virtual void sync() {}
  /// Runs `then` once every change applied before the call is on the disk, without making the caller wait (from
  /// any thread; by default at once, after sync()).
  virtual void sync_async(std::function<void()> then) {
    sync();
    then();
  }
};

}  // namespace tessera::server
