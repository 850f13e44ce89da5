// The farm's job/tile/lease state machine: no I/O, an injected clock, every operation one atomic step, whose changes
// go to an injected SchedulerStore as one batch (one transaction when the store is a database). This class holds the
// lock, the clock and the state, and hands each operation to the part that does it: server/lease_flow.h (workers),
// server/job_control.h (operators), server/farm_queries.h (views), over server/farm_state.h, persisted through
// server/change_log.h.
#pragma once

#include "protocol/tile.h"
#include "protocol/worker.h"
#include "server/farm_queries.h"
#include "server/farm_state.h"
#include "server/job_control.h"
#include "server/lease_flow.h"
#include "server/scheduler_store.h"
#include "server/scheduler_types.h"

#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// The job/tile/lease state machine. Thread-safe: each call takes one lock and is one atomic step. Expired leases are
/// reclaimed at the start of every call, and leases older than their job's tile_timeout_seconds (since the grant) are
/// revoked as failures of their workers ("tile timed out after N s"), and workers past their retention are forgotten,
/// so behaviour depends only on the injected clock.
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
  const SchedulerConfig& config() const { return state_.config; }

  /// Calls `noted` whenever tiles may have become leasable: a job added, resumed or retried, a tile pending again, a
  /// worker undrained. It runs under the scheduler's lock, so it must only take note (never call the scheduler). Set
  /// before the scheduler is shared.
  void on_work(std::function<void()> noted) { state_.work_noted = std::move(noted); }

  /// A fresh job id for add_job (so the caller can store the job's record before the job becomes leasable).
  std::string new_job_id();
  /// Adds a queued job under `id` (empty: a fresh one) and returns the id; throws std::invalid_argument for bad
  /// sizes or an id already in use, and what the store throws (the job is then not added).
  std::string add_job(const JobParams& params, const std::string& id = "");
  /// Adds a queued sequence under `id` (empty: a fresh one) with a job per frame (frame_job_id), in frame order, in
  /// one change, and returns the id; throws as add_job (a frame's bad size names the frame), and
  /// std::invalid_argument when the frames are not in increasing number order.
  std::string add_sequence(const JobParams& params, const std::vector<FrameParams>& frames, const std::string& id = "");
  /// A page of a sequence's frames numbered above `after` (all: nothing), at most `limit` (0: all); nothing for an
  /// unknown id or a job that is not a sequence.
  std::optional<FramePage> frames(const std::string& id, std::optional<int64_t> after, size_t limit);
  /// A job's snapshot, or nothing for an unknown id.
  std::optional<JobStatus> job(const std::string& id);
  /// All jobs, newest first (a sequence as one job: its frames are not listed).
  std::vector<JobStatus> jobs();
  /// The jobs a query asks for, newest first.
  JobPage jobs(const JobQuery& query);
  /// The user who owns a job (a frame: its sequence's), or nothing for an unknown id.
  std::optional<std::string> job_owner(const std::string& id);
  /// The submission number of a job (what a listing cursor holds), or nothing for an unknown id.
  std::optional<uint64_t> job_seq(const std::string& id);

  /// Registers a worker (announcing `threads` render threads, 0 unknown, and offering `tags`, sorted) with a fresh
  /// secret; refused (full) when max_workers are registered.
  RegisterResult register_worker(const std::string& name, int64_t threads = 0, const std::vector<std::string>& tags = {});
  /// Sets each user's weight and cap (users not named weigh 1 with no cap); the next lease follows them.
  void set_shares(std::map<std::string, OwnerShare, std::less<>> shares);
  /// Whether `secret` is the secret of the worker `worker` (a lease request's check).
  WorkerCheck check_worker(const std::string& worker, std::string_view secret);
  /// Whether `secret` is the secret of the worker the lease was granted to (the check of every request on a lease);
  /// sets `holder` to that worker's id when the lease exists. The lease's worker never changes, so a request that
  /// passes may act on the lease.
  WorkerCheck check_lease_holder(const std::string& lease, std::string_view secret, std::string* holder);
  /// One registered worker with its state, as workers() lists it, or nothing for an unknown id.
  std::optional<protocol::WorkerInfo> worker(const std::string& id);
  /// Every registered worker with its state (offline after worker_gone_ms without a request), lease and blocklists.
  std::vector<protocol::WorkerInfo> workers();
  /// Drains a worker (true: it finishes its current tile, then every lease request answers no work) or undrains it;
  /// the worker as it is now, nullopt for unknown ids. Stored: a restarted coordinator keeps the worker drained.
  std::optional<protocol::WorkerInfo> set_drained(const std::string& worker, bool drained);
  /// True when the worker id is registered.
  bool has_worker(const std::string& id);

  /// Leases the lowest pending tile of a job the worker may take (its tags include the job's requirements, the job
  /// and its owner are under their caps, the worker is not blocklisted for it, it is not paused): the job of the owner
  /// furthest below its weighted share of the leases, and within an owner the highest-priority (then oldest) job. A
  /// drained worker gets no work.
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
  /// `log` is the log its worker sent with it, kept with the tile within the job's bound
  /// (SchedulerConfig::job_tile_log_bytes). Returns once the change is on the disk (SchedulerStore::sync).
  FinishResult finish_result(const std::string& lease, uint64_t rays = 0, std::string_view pixels = {},
                             std::vector<std::string> log = {});
  /// As finish_result, but returns once the change is committed; `durable` runs (on another thread, or on this one
  /// when the store does not flush) once it is on the disk: only then may the upload be acknowledged.
  void finish_result(const std::string& lease, uint64_t rays, std::string_view pixels, std::vector<std::string> log,
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
  RetryResult retry(const std::string& job, const std::vector<int64_t>& frames = {});
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
  /// later requests on its leases are answered as for unknown leases. When the store cannot take the change (the disk
  /// is full), the job is forgotten all the same and its rows go with the next change the store takes.
  PurgeResult purge(const std::string& job);
  /// Marks a job whose tiles are all merged done (after its image was written).
  void complete_job(const std::string& job);
  /// Marks an unfinished job failed with a reason.
  void fail_job(const std::string& job, const std::string& error);

  /// Reclaims expired leases and forgets workers past their retention now (also done at the start of every other call).
  void expire();
  /// Current counters.
  SchedulerCounters counters();
  /// Every tile of a job in index order with its lease holder, attempts, render time, rays and failures, or nothing
  /// for an unknown job.
  std::optional<protocol::TileList> tiles(const std::string& job);
  /// Ids of jobs that are running (or paused after starting) with every tile done (a restart came between the last
  /// tile and the result file).
  std::vector<std::string> unfinalized_jobs();
  /// Stores the changes still waiting after a store failed (reads and heartbeats go on without storing theirs);
  /// throws what the store throws, keeping them.
  void store_pending();

 private:
  // When an operation's changes go to the store.
  enum class Store {
    now,        // before the operation returns; a store failure fails the operation
    later,      // with the next operation that stores (changes a restart may safely forget)
    if_it_can,  // now, but a store failure leaves them for the next one and the operation still answers (views,
                // heartbeats: the disk being full must not stop them)
  };
  // Runs f(now) as one operation under the lock, then stores its changes (see scheduler.cpp).
  template <class F>
  auto transact(F&& f, Store store = Store::now, std::function<void()> durable = {});

  ClockMs clock_;                // the injected time
  std::mutex mu_;                // held by every operation
  FarmState state_;              // everything the scheduler knows (mu_)
  LeaseFlow leases_{state_};     // the workers' operations on state_
  JobControl control_{state_};   // the operators' operations on state_
  FarmQueries views_{state_};    // the read-only views of state_
};

}  // namespace tessera::server
