// The scheduler's side of persistence: which rows an operation changed (jobs, tiles, leases, workers, purges), written
// to the SchedulerStore as one batch when the operation ends, and the state rebuilt from what a store holds.
#pragma once

#include "server/scheduler_store.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tessera::server {

struct FarmState;

/// The rows changed since the last write to the store. Not thread-safe: the scheduler uses it under its lock.
class ChangeLog {
 public:
  /// A log writing to `store` (nullptr: memory only, every flush just forgets the changes).
  explicit ChangeLog(SchedulerStore* store) : store_(store) {}

  /// The store it writes to (nullptr: none).
  SchedulerStore* store() const { return store_; }

  /// The job's row changed.
  void touch_job(const std::string& job) { jobs_.insert(job); }
  /// The row of tile `tile` of `job` changed.
  void touch_tile(const std::string& job, int64_t tile) { tiles_.emplace(job, tile); }
  /// The lease's row changed.
  void touch_lease(const std::string& lease) { leases_.insert(lease); }
  /// The worker is new, or was drained or undrained.
  void touch_worker(const std::string& worker) { workers_.insert(worker); }
  /// The worker was forgotten: its row goes.
  void forget_worker(const std::string& worker) {
    workers_.erase(worker);
    forgotten_workers_.insert(worker);
  }
  /// A worker was added to the end of a job's list of workers.
  void add_job_worker(JobWorkerRow row) { job_workers_.push_back(std::move(row)); }
  /// Takes back the last add_job_worker (its tile was not stored).
  void drop_last_job_worker() { job_workers_.pop_back(); }
  /// The pixels of the tile that became done in this operation, stored with its row; must outlive the next flush.
  void set_done_pixels(const std::string& job, int64_t tile, std::string_view pixels) {
    done_pixels_.emplace(std::make_pair(job, tile), pixels);
  }
  /// The lease is gone (its job was purged): no row of it is written.
  void forget_lease(const std::string& lease) { leases_.erase(lease); }
  /// The job is gone with every row of it: none is written, and the store deletes them.
  void purge_job(const std::string& job);
  /// A webhook event to store with the changes (server/outbox.h).
  void add_outbox(OutboxRow row) { outbox_.push_back(std::move(row)); }
  /// The job was never stored and is taken back: none of its rows is written.
  void withdraw_job(const std::string& job);
  /// The changes include an acknowledgement: once they are stored, the operation syncs the store before it returns.
  void need_sync() { sync_needed_ = true; }
  /// The counters as the store held them when the state was loaded from it.
  void loaded(const CounterRow& stored) { flushed_counters_ = stored; }

  /// Writes every change since the last flush, with the counters, to the store as one batch; throws what the store
  /// throws, keeping the changes so the next flush writes them again.
  void flush(FarmState& s);
  /// True once when a flush since the last call stored an acknowledgement (see need_sync).
  bool take_sync_due() { return std::exchange(sync_due_, false); }

 private:
  void clear();

  SchedulerStore* store_;
  std::set<std::string> jobs_, leases_, workers_, forgotten_workers_;
  std::vector<JobWorkerRow> job_workers_;         // workers added to jobs' lists since the last flush
  std::set<std::pair<std::string, int64_t>> tiles_;
  std::set<std::string> purged_jobs_;             // purged since the last flush
  std::vector<OutboxRow> outbox_;                 // webhook events since the last flush
  std::optional<std::pair<std::pair<std::string, int64_t>, std::string_view>> done_pixels_;  // tile -> pixels
  CounterRow flushed_counters_;                   // counters as last stored
  bool sync_needed_ = false;                      // the pending changes include an acknowledgement
  bool sync_due_ = false;                         // such changes were stored: sync() before the operation returns
};

/// Rebuilds `s` (fresh) from what a store holds: leases that were live stay live with their deadline moved to now +
/// lease_ms, tiles that were being merged are pending again, and every stored worker counts as seen now; throws
/// std::invalid_argument for rows that belong to no stored job.
void restore(FarmState& s, SchedulerSnapshot snap, int64_t now);

}  // namespace tessera::server
