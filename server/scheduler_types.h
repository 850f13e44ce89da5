// Plain types shared by the scheduler (server/scheduler.h), its parts and its stores: the clock, the tunables, the
// outcome of each operation and the listing query.
#pragma once

#include "core/image/image.h"
#include "protocol/job.h"
#include "protocol/lease.h"
#include "protocol/messages.h"
#include "protocol/tile.h"

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace tessera::server {

/// Milliseconds since the Unix epoch (or any fixed origin in tests); injected so tests control time.
using ClockMs = std::function<int64_t()>;

// The protocol's job, tile and lease types are the scheduler's own (protocol/job.h, tile.h, lease.h, messages.h).
using protocol::is_final;
using protocol::is_held;
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
  int64_t lease_ms = int64_t(protocol::kDefaultLeaseSeconds * 1000);  ///< Lease length; every heartbeat moves the deadline to now + lease_ms.
  int tile_failure_workers = 3;    ///< Distinct workers failing one tile that fail the job.
  int worker_failure_limit = 2;    ///< Failures after which a worker is blocklisted for a job.
  std::string id_tag;              ///< Inserted into generated ids ("j-<tag>-1") so ids differ between runs.
  int64_t worker_gone_ms = 0;      ///< A worker not seen for this long no longer counts as present (0: 3 leases).
  int64_t max_workers = 10000;     ///< Registered workers at most; more registrations are refused (0: no bound).
  /// A worker that is not present, holds no live lease and was not seen for this long is forgotten (0: never).
  int64_t worker_retention_ms = 86'400'000;
  std::vector<std::string> webhooks{};  ///< Addresses told of every job's end (server/outbox.h); none: only jobs' own.
  /// Bytes of done tiles' logs kept per job at most; a log beyond it is not kept, and counted (0: none kept).
  int64_t job_tile_log_bytes = int64_t(1) << 20;
};

/// Outcome of registering a worker.
struct RegisterResult {
  enum Status { registered, full } status = registered;  ///< full: max_workers are registered, none was added.
  std::string id;      ///< The new worker's id.
  std::string secret;  ///< Its secret, for the worker alone: the scheduler keeps only its hash (server/worker_secret.h).
};

/// Whether a request that acts as a worker comes from that worker.
enum class WorkerCheck {
  ok,              ///< The secret is the worker's.
  unknown_lease,   ///< No such lease.
  unknown_worker,  ///< No such worker (never registered, or forgotten): it registers again.
  wrong_secret,    ///< The worker exists and the secret presented (maybe none) is not its own.
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

/// Outcome of retrying a job (or chosen frames of a sequence).
struct RetryResult {
  /// retried: queued again; not_ended: still queued or running (a sequence: no chosen frame failed or was
  /// cancelled); done: nothing to retry; no_frame: the sequence has no frame `frame`; unknown: no such job.
  enum Status { retried, not_ended, done, no_frame, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it had.
  int64_t pending = 0;              ///< Tiles to render again (done tiles are kept).
  int64_t frame = 0;                ///< no_frame: the number asked for.
  std::vector<std::string> jobs;    ///< The jobs put back in the queue (the job, or the sequence's frames).
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
  /// being stored (try again); holds: jobs wait for it or are blocked by it (`held`); unknown: no such job.
  enum Status { purged, not_ended, busy, holds, unknown } status = unknown;
  JobState was = JobState::queued;  ///< The state it had.
  std::vector<std::string> held;    ///< holds: the jobs it holds back.
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

/// One frame of a sequence as add_sequence takes it: its number and what its image is.
struct FrameParams {
  int64_t number = 0;      ///< Frame number.
  int width = 0;           ///< Image columns.
  int height = 0;          ///< Image rows.
  uint32_t spp = 1;        ///< Samples per pixel (the frame's scene's, unless the submission set one).
  std::string scene_hash;  ///< The loader's content hash of the frame's scene and assets.
};

using protocol::frame_job_id;

/// One page of a sequence's frames, in frame order.
struct FramePage {
  std::vector<JobStatus> frames;  ///< The frames' snapshots.
  bool more = false;              ///< More frames follow the last one.
};

/// Which jobs a listing wants: states (empty: all), an owner, at most `limit` (0: no limit), older than the job with
/// `after_seq`.
struct JobQuery {
  std::set<JobState> states;      ///< Wanted states; empty means every state.
  size_t limit = 0;               ///< Most jobs in the answer; 0: all.
  std::optional<uint64_t> after;  ///< Only jobs submitted before the one with this seq (a cursor).
  std::string owner;              ///< Only this user's jobs ("": everyone's).
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

}  // namespace tessera::server
