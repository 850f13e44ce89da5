// The farm's job/tile/lease state machine: no I/O, an injected clock, every operation one atomic step, whose changes
// go to an injected SchedulerStore as one batch (one transaction when the store is a database).
#pragma once

#include "core/image/image.h"
#include "protocol/job.h"
#include "protocol/lease.h"
#include "protocol/worker.h"
#include "protocol/messages.h"
#include "protocol/tile.h"

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

namespace tessera::server {

/// Milliseconds since the Unix epoch (or any fixed origin in tests); injected so tests control time.
using ClockMs = std::function<int64_t()>;

// The protocol's job, tile and lease types are the scheduler's own (protocol/job.h, tile.h, lease.h, messages.h).
using protocol::is_final;
using protocol::to_string;
using protocol::job_state_from_string;
using protocol::JobParams;
using protocol::JobState;
using protocol::JobStatus;
using protocol::Lease;
using protocol::TileCounts;
using protocol::TileState;
using protocol::LeaseState;
using protocol::tile_state_from_string;
using protocol::lease_state_from_string;

/// Scheduler tunables.
struct SchedulerConfig {
  int64_t lease_ms = 30'000;       ///< Lease length; every heartbeat moves the deadline to now + lease_ms.
  int tile_failure_workers = 3;    ///< Distinct workers failing one tile that fail the job.
  int worker_failure_limit = 2;    ///< Failures after which a worker is blocklisted for a job.
  std::string id_tag;              ///< Inserted into generated ids ("j-<tag>-1") so ids differ between runs.
  int64_t worker_gone_ms = 0;      ///< A worker not seen for this long no longer counts as present (0: 3 leases).
};

/// Outcome of asking for work.
struct AcquireResult {
  enum Status { granted, no_work, unknown_worker } status = no_work;  ///< What happened.
  Lease lease;  ///< The lease when granted.
  JobState job_state = JobState::running;  ///< The state of the lease's job after the grant.
};

/// Outcome of a heartbeat.
struct HeartbeatResult {
  enum Status { ok, gone, unknown } status = unknown;  ///< ok: extended; gone: revoked/expired/ended (410).
  int64_t deadline_ms = 0;  ///< New deadline when ok.
};

/// Outcome of checking or claiming a lease's result upload.
struct ResultClaim {
  /// proceed: merge it; duplicate: tile already done (200); discarded: job ended (410); unknown: no such lease (404).
  enum Status { proceed, duplicate, discarded, unknown } status = unknown;
  std::string job;      ///< Job id.
  std::string worker;   ///< Worker that held the lease.
  int64_t tile = 0;     ///< Tile index.
  PixelWindow window;   ///< Tile pixels.
  int width = 0;        ///< Full image columns.
  int height = 0;       ///< Full image rows.
  uint32_t spp = 0;     ///< The job's samples per pixel (a lease of another spp, from before a raise, is discarded).
};

/// Outcome of finishing a claimed result.
struct FinishResult {
  bool last = false;  ///< Every tile of the job is now merged: write the final image, then call complete_job.
};

/// Outcome of a failure report.
struct FailResult {
  enum Status { recorded, unknown } status = unknown;  ///< unknown: no such lease.
  bool blocklisted = false;  ///< The worker is now blocklisted for the job.
  bool job_failed = false;   ///< The job failed because of this report.
};

/// Outcome of cancelling a job.
struct CancelResult {
  enum Status { cancelled, already_ended, unknown } status = unknown;  ///< What happened.
  int revoked_leases = 0;  ///< Leases revoked.
};

/// Outcome of retrying a job.
struct RetryResult {
  /// retried: queued again; not_ended: still queued or running; done: nothing to retry; unknown: no such job.
  enum Status { retried, not_ended, done, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it had.
  int64_t pending = 0;              ///< Tiles to render again (done tiles are kept).
};

/// Outcome of pausing or resuming a job.
struct PauseResult {
  /// changed: now paused (or resumed); wrong_state: the job is not in a state that allows it; unknown: no such job.
  enum Status { changed, wrong_state, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it had.
};

/// Outcome of changing a job's priority.
struct PriorityResult {
  /// changed: the queue uses the new priority; ended: the job is done, failed or cancelled; unknown: no such job.
  enum Status { changed, ended, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it has.
};

/// Outcome of raising a job's spp.
struct RaiseResult {
  /// raised: running (or queued, paused) again at the new spp; wrong_state: failed or cancelled; not_higher: the spp
  /// is not above the job's; merging: an upload is being merged (retry in a moment); unknown: no such job.
  enum Status { raised, wrong_state, not_higher, merging, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it had.
  int revoked_leases = 0;           ///< Leases of the old spp revoked.
  JobStatus job;                    ///< The job as raised (when raised), before any worker took a tile.
};

/// Outcome of purging a job.
struct PurgeResult {
  /// purged: gone from memory and store; not_ended: queued, running or paused; busy: an upload of one of its tiles is
  /// being stored (try again); unknown: no such job.
  enum Status { purged, not_ended, busy, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it had.
};

/// Which jobs a listing wants: states (empty: all), at most `limit` (0: no limit), older than the job with `after_seq`.
struct JobQuery {
  std::set<JobState> states;      ///< Wanted states; empty means every state.
  size_t limit = 0;               ///< Most jobs in the answer; 0: all.
  std::optional<uint64_t> after;  ///< Only jobs submitted before the one with this seq (a cursor).
};

/// One page of a listing, newest first.
struct JobPage {
  std::vector<JobStatus> jobs;   ///< The jobs.
  std::vector<uint64_t> seqs;    ///< Their submission numbers (for cursors), in the same order.
  bool more = false;             ///< More jobs match after the last one.
};

/// Counters for /metrics.
struct SchedulerCounters {
  std::map<JobState, int64_t> jobs;   ///< Jobs by state.
  uint64_t tiles_rendered = 0;        ///< Tiles merged.
  uint64_t lease_expiries = 0;        ///< Leases that expired.
  uint64_t rays = 0;                  ///< Rays reported by workers.
  int64_t workers = 0;                ///< Registered workers.
  int64_t active_leases = 0;          ///< Live leases.
};

/// Outcome of requeueing one tile.
struct RequeueResult {
  /// requeued: pending again; wrong_job_state: the job is queued, done or cancelled; wrong_tile_state: the tile is
  /// pending without failures or an upload of it is being stored; no_tile: no such tile; unknown: no such job.
  enum Status { requeued, wrong_job_state, wrong_tile_state, no_tile, unknown } status = unknown;
  JobState job_state = JobState::queued;     ///< The job's state.
  TileState was = TileState::pending;        ///< The tile's state before.
  int64_t tiles = 0;                         ///< Tiles in the job.
  bool revoked = false;                      ///< A live lease on it was revoked.
};

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
  std::vector<std::string> purged_jobs;  ///< Jobs whose every row (job, tiles, leases, record) goes.
  CounterRow counters;             ///< Counters after the operation.
  /// True when nothing but the counters changed.
  bool empty() const {
    return jobs.empty() && job_workers.empty() && tiles.empty() && leases.empty() && workers.empty() && purged_jobs.empty();
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

/// The job/tile/lease state machine. Thread-safe: each call takes one lock and is one atomic step. Expired leases are
/// reclaimed at the start of every call, and leases older than their job's tile_timeout_seconds (since the grant) are
/// revoked as failures of their workers ("tile timed out after N s"), so behaviour depends only on the injected clock.
class Scheduler {
 public:
  /// A scheduler reading time from `clock`, keeping its state in memory only.
  Scheduler(SchedulerConfig config, ClockMs clock);
  /// A scheduler whose every operation is applied to `store` (which must outlive it), starting from what the store
  /// holds: leases that were live stay live with their deadline moved to now + lease_ms (their workers may come back),
  /// tiles that were being merged are pending again, and every stored worker counts as seen now.
  Scheduler(SchedulerConfig config, ClockMs clock, SchedulerStore& store);
  ~Scheduler();
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  /// The configuration it runs with.
  const SchedulerConfig& config() const { return config_; }

  /// Calls `noted` whenever tiles may have become leasable: a job added, resumed or retried, a tile pending again, a
  /// worker undrained. It runs under the scheduler's lock, so it must only take note (never call the scheduler). Set
  /// before the scheduler is shared.
  void on_work(std::function<void()> noted) { work_noted_ = std::move(noted); }

  /// A fresh job id for add_job (so the caller can store the job's record before the job becomes leasable).
  std::string new_job_id();
  /// Adds a queued job under `id` (empty: a fresh one) and returns the id; throws std::invalid_argument for bad
  /// sizes or an id already in use.
  std::string add_job(const JobParams& params, const std::string& id = "");
  /// A job's snapshot, or nothing for an unknown id.
  std::optional<JobStatus> job(const std::string& id);
  /// All jobs, newest first.
  std::vector<JobStatus> jobs();
  /// The jobs a query asks for, newest first.
  JobPage jobs(const JobQuery& query);
  /// The submission number of a job (what a listing cursor holds), or nothing for an unknown id.
  std::optional<uint64_t> job_seq(const std::string& id);

  /// Registers a worker (announcing `threads` render threads, 0 unknown) and returns its id.
  std::string register_worker(const std::string& name, int64_t threads = 0);
  /// Every registered worker with its state (offline after worker_gone_ms without a request), lease and blocklists.
  std::vector<protocol::WorkerInfo> workers();
  /// Drains a worker (true: it finishes its current tile, then every lease request answers no work) or undrains it;
  /// the worker as it is now, nullopt for unknown ids. Not stored: a restarted coordinator forgets it.
  std::optional<protocol::WorkerInfo> set_drained(const std::string& worker, bool drained);
  /// True when the worker id is registered.
  bool has_worker(const std::string& id);

  /// Leases the lowest pending tile of the highest-priority (then oldest) job that is not paused and the worker is not
  /// blocklisted for; a drained worker gets no work.
  AcquireResult acquire(const std::string& worker);
  /// How many tiles acquire() could lease to the worker now (0 for an unknown or drained worker); changes nothing.
  int64_t leasable_tiles(const std::string& worker);
  /// Extends a live lease to now + lease_ms and adds `rays` to the job's count.
  HeartbeatResult heartbeat(const std::string& lease, uint64_t rays = 0);

  /// Read-only look at what an upload for this lease would do (no state change), to skip parsing duplicates.
  ResultClaim check_result(const std::string& lease);
  /// Claims the lease's tile for merging: on proceed the tile is reserved (no other upload merges it) until
  /// finish_result or abandon_result. Other live leases on the tile are revoked.
  ResultClaim claim_result(const std::string& lease);
  /// Marks a claimed tile done with its validated `pixels` (stored with the tile in the same change, so a tile is never
  /// done without them); `rays` adds to the job's count. When the store fails, the tile stays claimed and this throws.
  /// Returns once the change is on the disk (SchedulerStore::sync).
  FinishResult finish_result(const std::string& lease, uint64_t rays = 0, std::string_view pixels = {});
  /// As finish_result, but returns once the change is committed; `durable` runs (on another thread, or on this one
  /// when the store does not flush) once it is on the disk: only then may the upload be acknowledged.
  void finish_result(const std::string& lease, uint64_t rays, std::string_view pixels,
                     std::function<void(FinishResult)> durable);
  /// Runs `then` once every change stored so far is on the disk (at once without a store): a duplicate upload is
  /// acknowledged only once the tile it duplicates is durable.
  void after_sync(std::function<void()> then);
  /// Gives up a claimed tile's merge (it failed for a reason that is not the worker's, who retries the upload): the
  /// tile is leased again by that lease, live for a lease length, when it was live at the claim; else it is pending.
  void abandon_result(const std::string& lease);

  /// Records that the lease's worker could not render its tile, with the log lines it sent; see docs/protocol.md for
  /// blocklists and job failure.
  FailResult fail(const std::string& lease, const std::string& error, const std::vector<std::string>& log = {});
  /// Hands a live lease's tile back without counting a failure; false for an unknown lease.
  bool release(const std::string& lease);

  /// Cancels a queued or running job and revokes its leases.
  CancelResult cancel(const std::string& job);
  /// Puts a failed or cancelled job back in the queue keeping its done tiles; its failure counts, blocklists and
  /// error are cleared. A job whose every tile is done becomes running with nothing to lease (see unfinalized_jobs).
  RetryResult retry(const std::string& job);
  /// Pauses a queued or running job: it gets no new leases; its live leases go on and their uploads are accepted (a
  /// paused job whose last tile lands is done, see ResultClaim::last).
  PauseResult pause(const std::string& job);
  /// Renders a tile of a running, paused or failed job again: a done tile becomes pending (its stored pixels stay until
  /// a new upload replaces them), a leased one loses its lease (revoked: the worker's heartbeat answers 410), a pending
  /// one that failed forgets its failures (its workers' failure counts stay). A failed job renders it when retried.
  RequeueResult requeue(const std::string& job, int64_t tile);
  /// Resumes a paused job: running again if it had started, else queued.
  PauseResult resume(const std::string& job);
  /// Changes the priority of a job that has not ended; its next tiles are leased in the new order.
  PriorityResult set_priority(const std::string& job, int priority);
  /// Raises a job's spp (the caller checks it can be exact, server/job_refine.h): its live leases are revoked and every
  /// tile is pending again; a done job is running again. Uploads of leases at the old spp are discarded from then on.
  RaiseResult raise_spp(const std::string& job, uint32_t spp);
  /// Forgets a done, failed or cancelled job: its job, tile and lease rows (and its stored record) go in one change;
  /// later requests on its leases are answered as for unknown leases.
  PurgeResult purge(const std::string& job);
  /// Marks a job whose tiles are all merged done (after its image was written).
  void complete_job(const std::string& job);
  /// Marks an unfinished job failed with a reason.
  void fail_job(const std::string& job, const std::string& error);

  /// Reclaims expired leases now (also done at the start of every other call).
  void expire();
  /// Current counters.
  SchedulerCounters counters();
  /// Every tile of a job in index order with its lease holder, attempts, render time, rays and failures, or nothing
  /// for an unknown job.
  std::optional<protocol::TileList> tiles(const std::string& job);
  /// Ids of jobs that are running (or paused after starting) with every tile done (a restart came between the last
  /// tile and the result file).
  std::vector<std::string> unfinalized_jobs();

 private:
  struct Tile {
    TileState state = TileState::pending;
    std::string lease;                               // live lease or claiming lease
    std::map<std::string, std::string> failures;     // worker -> last error text
    std::map<std::string, std::vector<std::string>> logs;  // worker -> log lines of its last failure
    int64_t attempts = 0;                            // leases granted
    int64_t render_ms = -1;                          // grant to upload of the accepted result
    uint64_t rays = 0;                               // rays of the accepted result's lease
    std::string rendered_by;                         // the worker whose result was accepted
    bool unflushed = false;                          // done and committed, its flush not returned yet
  };
  struct JobRec {
    JobStatus status;
    uint64_t seq = 0;
    std::vector<Tile> tiles;
    std::set<int64_t> pending;
    std::map<std::string, int> worker_failures;
    std::map<std::string, std::string> worker_last_error;  // worker -> the latest error it reported on this job
    std::set<std::string> worker_set;                      // status.workers, for lookups
    int64_t unflushed = 0;                                 // tiles done but not yet flushed (Tile::unflushed)
  };
  struct LeaseRec {
    Lease lease;
    LeaseState state = LeaseState::live;
    int64_t granted_ms = 0;
    uint64_t rays = 0;  // reported by heartbeats (not stored: a restarted lease counts from zero)
    bool live_at_claim = false;  // it was live when its upload claimed the tile (abandon_result gives it back)
  };
  struct WorkerRec {
    std::string name;
    int64_t last_seen_ms = 0;  // register, lease request, heartbeat, upload or failure report
    int64_t threads = 0;       // announced at registration (0: unknown, e.g. after a restart)
    int64_t tiles_done = 0;    // accepted uploads since this coordinator started
    uint64_t rays = 0;         // rays of those tiles
    int64_t render_ms = 0;     // their render times (lease grant to acceptance), summed
    bool drained = false;      // no new leases
  };
  using QueueKey = std::tuple<int, int64_t, uint64_t>;  // (-priority, created_ms, seq)

  template <class F>
  auto transact(F&& f, bool store_now = true, std::function<void()> durable = {});
  template <class R, class F>
  R with_job(const std::string& job, F&& f);
  static bool has_merging_tile(const JobRec& j);  // an upload of one of its tiles is being stored
  void restore_locked(SchedulerSnapshot snap, int64_t now);
  void flush_locked();
  void touch_job(const JobRec& j) { dirty_jobs_.insert(j.status.id); }
  void touch_tile(const JobRec& j, int64_t tile) { dirty_tiles_.emplace(j.status.id, tile); }
  void touch_lease(const LeaseRec& l) { dirty_leases_.insert(l.lease.id); }
  void seen_locked(const std::string& worker, int64_t now);
  bool blocklisted_locked(const JobRec& j, const std::string& worker) const;  // too many failures on j
  void work_appeared_locked() const {
    if (work_noted_) work_noted_();
  }
  PauseResult set_paused(const std::string& job, bool paused);  // pause (true) or resume (false)
  int64_t gone_ms() const;  // a worker not seen for this long is offline
  protocol::WorkerInfo worker_info_locked(const std::string& id, const WorkerRec& w, int64_t now) const;
  // The same from the worker's lease (nullptr: none) and the jobs it is blocklisted for, gathered by the caller.
  protocol::WorkerInfo worker_info_locked(const std::string& id, const WorkerRec& w, int64_t now, const Lease* holding,
                                          std::vector<std::string> blocklisted_for) const;
  bool all_present_blocklisted_locked(const JobRec& j, int64_t now, size_t* present) const;
  bool fail_if_all_blocklisted_locked(JobRec& j, int64_t now);
  void expire_locked(int64_t now);
  /// Counts a failure of the lease's worker on its tile (ends the lease, returns the tile to pending, blocklists the
  /// worker, fails the job by the thresholds of SchedulerConfig).
  FailResult record_failure_locked(JobRec& j, LeaseRec& l, const std::string& error, std::vector<std::string> log,
                                   int64_t now);
  /// Hands a tile back to the queue: pending, no lease, leasable again.
  void return_to_pending_locked(JobRec& j, int64_t tile);
  void end_lease_locked(LeaseRec& l, LeaseState to);
  void finish_job_locked(JobRec& j, JobState to, int64_t now, std::optional<std::string> error);
  ResultClaim claim_view_locked(const std::string& lease, JobRec** job_out, LeaseRec** lease_out);
  FinishResult finish_result_locked(const std::string& lease, uint64_t rays, std::string_view pixels, int64_t now,
                                    std::pair<std::string, int64_t>* tile_key);
  // The tile's done state, committed earlier, is now on the disk: it counts as done in snapshots from now on.
  void flushed(const std::string& job, int64_t tile);
  JobStatus snapshot_locked(const JobRec& j, int64_t now) const;
  std::string next_id(char kind);

  SchedulerConfig config_;
  ClockMs clock_;
  std::function<void()> work_noted_;  // on_work
  std::mutex mu_;
  uint64_t next_seq_ = 1;
  std::map<std::string, std::unique_ptr<JobRec>> jobs_;
  std::map<QueueKey, JobRec*> queue_;                 // active (queued/running) jobs in scheduling order
  std::map<std::string, LeaseRec> leases_;            // every lease ever granted (answers 410 vs 404)
  std::set<std::string> live_leases_;
  // When lease l next needs a look: the first moment it has expired or timed out.
  int64_t expiry_check_ms(const LeaseRec& l) const;
  // No live lease can expire or time out before this (a lower bound: heartbeats only move deadlines later), so
  // expire_locked skips its scan of live_leases_ until then.
  int64_t next_expiry_check_ms_ = 0;
  std::map<std::string, WorkerRec> workers_;
  SchedulerStore* store_ = nullptr;                   // nullptr: memory only
  std::set<std::string> dirty_jobs_, dirty_leases_, new_workers_;
  std::vector<JobWorkerRow> new_job_workers_;         // workers added to jobs' lists since the last flush
  std::set<std::pair<std::string, int64_t>> dirty_tiles_;
  std::set<std::string> purged_jobs_;                 // purged since the last flush
  std::optional<std::pair<std::pair<std::string, int64_t>, std::string_view>> done_pixels_;  // tile -> pixels
  CounterRow flushed_counters_;                       // counters as last stored
  bool sync_needed_ = false;                          // the pending changes include an acknowledgement (see SchedulerStore::sync)
  bool sync_due_ = false;                             // such changes were stored: sync() before the operation returns
  uint64_t tiles_rendered_ = 0;
  uint64_t lease_expiries_ = 0;
  uint64_t rays_ = 0;
};

}  // namespace tessera::server
