// The scheduler's state in memory (jobs with their tiles, the scheduling queue, leases, workers, counters) and the
// transitions its operations share: ending a lease, handing a tile back to the queue, counting a worker's failure,
// ending a job. Every change is noted in the state's ChangeLog.
#pragma once

#include "server/change_log.h"
#include "server/dependencies.h"
#include "server/scheduler_types.h"
#include "server/worker_registry.h"

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

namespace tessera::server {

/// One tile of a job as the scheduler keeps it.
struct TileRec {
  TileState state = TileState::pending;                  ///< Where it is.
  std::string lease;                                     ///< The live lease, or the lease whose upload claimed it.
  std::map<std::string, std::string> failures;           ///< Worker -> last error text.
  std::map<std::string, std::vector<std::string>> logs;  ///< Worker -> log lines of its last failure.
  std::vector<std::string> log;                          ///< Done: the log lines sent with the accepted upload.
  bool log_not_kept = false;                             ///< Done: a log came, but the job's tile logs were full.
  int64_t attempts = 0;                                  ///< Leases granted.
  int64_t render_ms = -1;                                ///< Grant to upload of the accepted result.
  uint64_t rays = 0;                                     ///< Rays of the accepted result's lease.
  std::string rendered_by;                               ///< The worker whose result was accepted.
  bool unflushed = false;                                ///< Done and committed, its flush not returned yet.
};

/// One job as the scheduler keeps it.
struct JobRec {
  JobStatus status;                                      ///< Its snapshot (tile counts but done are derived).
  uint64_t seq = 0;                                      ///< Submission order.
  std::vector<TileRec> tiles;                            ///< Every tile, by index.
  std::set<int64_t> pending;                             ///< Indices of its pending tiles.
  std::map<std::string, int> worker_failures;            ///< Worker -> failures on this job.
  std::map<std::string, std::string> worker_last_error;  ///< Worker -> the latest error it reported on this job.
  std::set<std::string> worker_set;                      ///< status.workers, for lookups.
  int64_t unflushed = 0;                                 ///< Tiles done but not yet flushed (TileRec::unflushed).
  int64_t log_bytes = 0;                                 ///< Bytes of its tiles' kept logs (TileRec::log).
  int64_t logs_not_kept = 0;                             ///< Its tiles whose log was not kept (TileRec::log_not_kept).
  int64_t live = 0;  ///< Live leases on its tiles (a sequence: on its frames'), against params.max_workers.
  /// A sequence: its frames' jobs by frame number. A sequence has no tiles of its own and is never in the queue; its
  /// state is derived from its frames' (FarmState::snapshot).
  std::vector<JobRec*> frames;
  JobRec* sequence = nullptr;                            ///< A frame of a sequence: the sequence.
  /// True for a sequence.
  bool is_sequence() const { return status.frames.has_value(); }
};

/// One lease as the scheduler keeps it.
struct LeaseRec {
  Lease lease;                          ///< What was granted, with its current deadline.
  LeaseState state = LeaseState::live;  ///< Where it is.
  int64_t granted_ms = 0;               ///< When it was granted (the tile timeout counts from here).
  uint64_t rays = 0;                    ///< Reported by heartbeats (not stored: a restarted lease counts from zero).
  bool live_at_claim = false;           ///< It was live when its upload claimed the tile (abandon_result gives it back).
};

/// A user's part in sharing the farm (server/user_directory.h): its weight and its cap on tiles leased at once.
struct OwnerShare {
  double weight = 1;        ///< Its share of the rendering workers, relative to the other users with work.
  int64_t max_workers = 0;  ///< Its tiles leased at once at most; 0: no cap.
};

/// A job that has started and not ended: its last upload completes it.
inline bool started_and_open(const JobStatus& s) {
  return s.state == JobState::running || (s.state == JobState::paused && s.started_ms);
}

/// Everything the scheduler knows, with the transitions shared by its parts (server/lease_flow.h,
/// server/job_control.h, server/farm_queries.h). Not thread-safe: the scheduler uses it under its lock.
struct FarmState {
  /// An empty farm run by `config` whose changes go to `store` (nullptr: memory only).
  FarmState(SchedulerConfig config, SchedulerStore* store);

  using QueueKey = std::tuple<int, int64_t, uint64_t>;  ///< (-priority, created_ms, seq): scheduling order.

  const SchedulerConfig config;                      ///< The tunables.
  std::function<void()> work_noted;                  ///< Scheduler::on_work.
  uint64_t next_seq = 1;                             ///< Next number in generated ids.
  std::map<std::string, std::unique_ptr<JobRec>> jobs;  ///< Every job by id.
  std::map<QueueKey, JobRec*> queue;                 ///< Active (queued, running, paused) jobs in scheduling order.
  std::map<std::string, LeaseRec> leases;            ///< Every lease ever granted (answers 410 vs 404).
  std::set<std::string> live_leases;                 ///< Ids of the live leases.
  WorkerRegistry workers;                            ///< Every registered worker.
  std::map<std::string, OwnerShare, std::less<>> shares;       ///< Users' weights and caps (others: 1, no cap).
  std::map<std::string, int64_t, std::less<>> live_by_owner;   ///< Live leases by their job's owner (none: absent).
  std::map<std::string, int64_t, std::less<>> queued_by_owner; ///< Jobs in the queue by owner (none: absent).
  ChangeLog changes;                                 ///< What changed since the last write to the store.
  DependencyIndex dependents;                        ///< Which jobs wait for which (server/dependencies.h).
  uint64_t tiles_rendered = 0;                       ///< Tiles merged.
  uint64_t lease_expiries = 0;                       ///< Leases that expired.
  uint64_t rays = 0;                                 ///< Rays reported by workers.

  /// A fresh id: kind ('j', 'w', 'l'), the config's id tag, the next number.
  std::string next_id(char kind);
  /// The counters as stored.
  CounterRow counter_row() const { return CounterRow{next_seq, tiles_rendered, lease_expiries, rays}; }
  /// The job, or nullptr for an unknown id.
  JobRec* find_job(const std::string& id);
  /// The job's snapshot at `now` (its tile counts derived from its tiles; a sequence's from its frames').
  JobStatus snapshot(const JobRec& j, int64_t now) const;
  /// A job's tile counts as a snapshot gives them (done only once flushed; pending and leased from its tiles).
  static TileCounts tile_counts(const JobRec& j);
  /// The state of a job: its own, or a sequence's as derived from its frames (see snapshot).
  JobState state_of(const JobRec& j) const;
  /// The job an operation on `j` ends at: a frame's sequence, or `j` itself.
  static JobRec& top(JobRec& j) { return j.sequence ? *j.sequence : j; }

  /// Puts the job in the scheduling queue.
  void enqueue(JobRec& j);
  /// Takes the job out of the scheduling queue.
  void dequeue(const JobRec& j);
  /// The share of a user (weight 1 and no cap for one the shares do not name).
  const OwnerShare& share_of(std::string_view owner) const;
  /// How many of the job's pending tiles its cap and its owner's let be leased now.
  int64_t leasable_now(const JobRec& j) const;
  /// Why a job with pending tiles is leased none for want of a worker with its tags, or nothing.
  std::optional<std::string> waiting_for(const JobRec& j, int64_t now) const;
  /// Tells whoever watches (on_work) that tiles may have become leasable.
  void work_appeared() const {
    if (work_noted) work_noted();
  }
  /// The job's row changed.
  void touch(const JobRec& j) { changes.touch_job(j.status.id); }
  /// The row of the job's tile changed.
  void touch(const JobRec& j, int64_t tile) { changes.touch_tile(j.status.id, tile); }

  /// True when the worker failed the job often enough to be blocklisted for it.
  bool blocklisted(const JobRec& j, const std::string& worker) const;
  /// Fails the job when every present worker is blocklisted for it (it could never finish); true when it did.
  bool fail_if_all_blocklisted(JobRec& j, int64_t now);
  /// Counts a failure of the lease's worker on its tile (ends the lease, returns the tile to pending, blocklists the
  /// worker, fails the job by the thresholds of SchedulerConfig).
  FailResult record_failure(JobRec& j, LeaseRec& l, const std::string& error, std::vector<std::string> log,
                            int64_t now);
  /// Keeps `log` as the done log of the job's tile `t` (in place of the one it had), or, when it would take the job's
  /// kept logs past config.job_tile_log_bytes, marks it not kept.
  void keep_tile_log(JobRec& j, TileRec& t, std::vector<std::string> log) const;
  /// Forgets the done log of the job's tile `t` (and that one was not kept).
  static void forget_tile_log(JobRec& j, TileRec& t);
  /// Hands a tile back to the queue: pending, no lease, leasable again.
  void return_to_pending(JobRec& j, int64_t tile);
  /// Makes a lease live (it counts against its job's and its owner's caps and shares).
  void go_live(const LeaseRec& l);
  /// Ends a lease in state `to` (no longer live).
  void end_lease(LeaseRec& l, LeaseState to);
  /// Revokes every live lease of the job, handing their tiles back to the queue; returns how many.
  int revoke_leases(JobRec& j);
  /// Ends the job in state `to` (done, failed, cancelled) with an error, revoking its live leases; returns how many.
  int finish_job(JobRec& j, JobState to, int64_t now, std::optional<std::string> error);
  /// A job's place in the queue.
  static QueueKey queue_key(const JobRec& j) { return {-j.status.params.priority, j.status.created_ms, j.seq}; }

 private:
  // Adds `delta` to the live leases counted for the job `job` and its owner.
  void count_live(const std::string& job, int64_t delta);
};

}  // namespace tessera::server
