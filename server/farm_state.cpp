#include "server/farm_state.h"

#include "protocol/tags.h"

#include <algorithm>
#include "server/outbox.h"

#include <set>
#include <string_view>
#include <utility>

namespace tessera::server {

namespace {

// "w-1: text; w-2: text": the error texts of a job's failing workers, for its failure reason.
std::string join_worker_errors(const std::map<std::string, std::string>& errors) {
  std::string out;
  for (const auto& [worker, text] : errors) out += (out.empty() ? "" : "; ") + worker + ": " + text;
  return out;
}

}  // namespace

FarmState::FarmState(SchedulerConfig c, SchedulerStore* store)
    : config(std::move(c)),
      workers(config.worker_gone_ms > 0 ? config.worker_gone_ms : 3 * config.lease_ms),
      changes(store) {}

std::string FarmState::next_id(char kind) {
  return std::string(1, kind) + "-" + (config.id_tag.empty() ? "" : config.id_tag + "-") + std::to_string(next_seq++);
}

JobRec* FarmState::find_job(const std::string& id) {
  const auto it = jobs.find(id);
  return it == jobs.end() ? nullptr : it->second.get();
}

namespace {

// A sequence's frame counts (with `total`, `first` and `last`) from its frames' states.
protocol::FrameCounts count_frames(const JobRec& seq) {
  protocol::FrameCounts c;
  c.total = int64_t(seq.frames.size());
  if (!seq.frames.empty()) {
    c.first = *seq.frames.front()->status.frame;
    c.last = *seq.frames.back()->status.frame;
  }
  for (const JobRec* f : seq.frames) {
    switch (f->status.state) {
      case JobState::queued: ++c.queued; break;
      case JobState::running: ++c.running; break;
      case JobState::paused: ++c.paused; break;
      case JobState::done: ++c.done; break;
      case JobState::failed: ++c.failed; break;
      case JobState::cancelled: ++c.cancelled; break;
      case JobState::waiting: ++c.waiting; break;
      case JobState::blocked: ++c.blocked; break;
    }
  }
  return c;
}

// A sequence's state from its frames': ended when every frame has (done if all are, else failed if one failed, else
// cancelled); otherwise paused when its unended frames are all paused, held when they are all held by dependencies
// (blocked if one is blocked, else waiting), running once a frame started or ended, or queued.
JobState sequence_state(const protocol::FrameCounts& c, bool started) {
  const int64_t open = c.queued + c.running + c.paused + c.waiting + c.blocked;
  if (open == 0) return c.done == c.total ? JobState::done : c.failed > 0 ? JobState::failed : JobState::cancelled;
  if (c.paused == open) return JobState::paused;
  if (c.waiting + c.blocked == open) return c.blocked > 0 ? JobState::blocked : JobState::waiting;
  return started ? JobState::running : JobState::queued;
}

}  // namespace

JobState FarmState::state_of(const JobRec& j) const {
  if (!j.is_sequence()) return j.status.state;
  bool started = false;
  for (const JobRec* f : j.frames) started = started || f->status.started_ms;
  return sequence_state(count_frames(j), started);
}

TileCounts FarmState::tile_counts(const JobRec& j) {
  TileCounts t = j.status.tiles;
  t.done -= j.unflushed;  // not durable yet: counted with the tiles in progress
  t.pending = int64_t(j.pending.size());
  t.leased = t.total - t.done - t.pending;
  return t;
}

JobStatus FarmState::snapshot(const JobRec& j, int64_t now) const {
  JobStatus s = j.status;
  if (!j.is_sequence()) {
    s.tiles = tile_counts(j);
  } else {
    // Summed from the frames' records as they are (a snapshot of each frame would copy it whole).
    s.frames = count_frames(j);
    s.tiles = {};
    s.rays = 0;
    s.workers.clear();
    std::set<std::string_view> seen;
    const JobRec* failed = nullptr;
    bool ended = true;
    for (const JobRec* f : j.frames) {
      const JobStatus& fs = f->status;
      const TileCounts t = tile_counts(*f);
      s.tiles.total += t.total;
      s.tiles.done += t.done;
      s.tiles.leased += t.leased;
      s.tiles.pending += t.pending;
      s.rays += fs.rays;
      for (const std::string& w : fs.workers)
        if (seen.insert(w).second) s.workers.push_back(w);
      if (fs.started_ms && (!s.started_ms || *fs.started_ms < *s.started_ms)) s.started_ms = fs.started_ms;
      ended = ended && fs.finished_ms;
      if (fs.finished_ms && (!s.finished_ms || *fs.finished_ms > *s.finished_ms)) s.finished_ms = fs.finished_ms;
      if (!failed && fs.state == JobState::failed) failed = f;
    }
    s.state = sequence_state(*s.frames, s.started_ms.has_value());
    if (!ended || !is_final(s.state)) s.finished_ms.reset();
    s.error.reset();
    if (s.state == JobState::failed && failed)
      s.error = std::to_string(s.frames->failed) + " of " + std::to_string(s.frames->total) + " frames failed; frame " +
                std::to_string(*failed->status.frame) + ": " + failed->status.error.value_or("(no error)");
  }
  if (s.started_ms) s.render_seconds = double(s.finished_ms.value_or(now) - *s.started_ms) / 1000.0;
  s.waiting_for = waiting_for(j, now);
  if (!j.status.params.pipeline.after.empty() || j.is_sequence()) s.reason = held_reason(*this, j);
  s.dependents = dependents_of(*this, j);
  return s;
}

bool FarmState::blocklisted(const JobRec& j, const std::string& worker) const {
  const auto wf = j.worker_failures.find(worker);
  return wf != j.worker_failures.end() && wf->second >= config.worker_failure_limit;
}

bool FarmState::fail_if_all_blocklisted(JobRec& j, int64_t now) {
  if (is_final(j.status.state)) return false;
  size_t present = 0;
  for (const auto& [id, w] : workers.all()) {
    if (!workers.present(w, now)) continue;  // died or left: it will not take this job's tiles
    ++present;
    if (!blocklisted(j, id)) return false;
  }
  if (present == 0) return false;
  // Failures spread over several tiles can blocklist every worker before any one tile fails on enough of them; the
  // job could then never finish, so it fails, with each worker's last error.
  finish_job(j, JobState::failed, now,
             "every registered worker that is still present (" + std::to_string(present) + ") failed " +
                 std::to_string(config.worker_failure_limit) + " tiles of this job and is blocklisted for it: " +
                 join_worker_errors(j.worker_last_error));
  return true;
}

FailResult FarmState::record_failure(JobRec& j, LeaseRec& l, const std::string& error, std::vector<std::string> log,
                                     int64_t now) {
  FailResult r;
  r.status = FailResult::recorded;
  TileRec& t = j.tiles[size_t(l.lease.tile)];
  const bool was_live = l.state == LeaseState::live;
  end_lease(l, LeaseState::failed);
  if (was_live && t.lease == l.lease.id) return_to_pending(j, l.lease.tile);
  const std::string& w = l.lease.worker;
  t.failures[w] = error;
  if (log.empty()) t.logs.erase(w);
  else t.logs[w] = std::move(log);
  const int n = ++j.worker_failures[w];
  j.worker_last_error[w] = error;
  touch(j, l.lease.tile);
  touch(j);
  r.blocklisted = n == config.worker_failure_limit;
  if (int(t.failures.size()) >= config.tile_failure_workers) {
    finish_job(j, JobState::failed, now,
               "tile " + std::to_string(l.lease.tile) + " failed on " + std::to_string(t.failures.size()) +
                   " workers: " + join_worker_errors(t.failures));
    r.job_failed = true;
    return r;
  }
  r.job_failed = fail_if_all_blocklisted(j, now);
  return r;
}

namespace {
int64_t log_size(const std::vector<std::string>& log) {
  int64_t n = 0;
  for (const std::string& line : log) n += int64_t(line.size());
  return n;
}
}  // namespace

void FarmState::keep_tile_log(JobRec& j, TileRec& t, std::vector<std::string> log) const {
  forget_tile_log(j, t);
  if (log.empty()) return;
  const int64_t size = log_size(log);
  if (j.log_bytes + size > config.job_tile_log_bytes) {
    t.log_not_kept = true;
    ++j.logs_not_kept;
    return;
  }
  j.log_bytes += size;
  t.log = std::move(log);
}

void FarmState::forget_tile_log(JobRec& j, TileRec& t) {
  j.log_bytes -= log_size(t.log);
  t.log.clear();
  if (std::exchange(t.log_not_kept, false)) --j.logs_not_kept;
}

void FarmState::return_to_pending(JobRec& j, int64_t tile) {
  TileRec& t = j.tiles[size_t(tile)];
  if (t.unflushed) {  // no longer done: its flush has nothing left to show
    t.unflushed = false;
    --j.unflushed;
  }
  t.state = TileState::pending;
  t.lease.clear();
  j.pending.insert(tile);
  touch(j, tile);
  work_appeared();
}

void FarmState::enqueue(JobRec& j) {
  if (queue.emplace(queue_key(j), &j).second) ++queued_by_owner[j.status.params.owner];
}

void FarmState::dequeue(const JobRec& j) {
  if (queue.erase(queue_key(j)) == 0) return;
  const auto it = queued_by_owner.find(j.status.params.owner);
  if (it != queued_by_owner.end() && --it->second <= 0) queued_by_owner.erase(it);
}

const OwnerShare& FarmState::share_of(std::string_view owner) const {
  static const OwnerShare kDefault;
  const auto it = shares.find(owner);
  return it == shares.end() ? kDefault : it->second;
}

std::optional<std::string> FarmState::waiting_for(const JobRec& j, int64_t now) const {
  const std::vector<std::string>& need = j.status.params.require;
  if (need.empty() || is_final(state_of(j))) return std::nullopt;
  for (const auto& [id, w] : workers.all())
    if (workers.present(w, now) && !w.drained && protocol::has_tags(w.tags, need)) return std::nullopt;
  return "a worker with tags " + protocol::tag_text(need);
}

void FarmState::count_live(const std::string& job, int64_t delta) {
  JobRec* j = find_job(job);
  if (!j) return;
  JobRec& t = top(*j);
  const bool job_was_capped = t.status.params.max_workers > 0 && t.live >= t.status.params.max_workers;
  t.live += delta;
  if (&t != j) j->live += delta;
  const std::string& owner = t.status.params.owner;
  const auto [it, added] = live_by_owner.try_emplace(owner, 0);
  const int64_t cap = share_of(owner).max_workers;
  const bool owner_was_capped = cap > 0 && it->second >= cap;
  if ((it->second += delta) <= 0) live_by_owner.erase(it);
  // A lease ended on a job or an owner at its cap: its pending tiles may be leased again.
  if (delta < 0 && (job_was_capped || owner_was_capped)) work_appeared();
}

int64_t FarmState::leasable_now(const JobRec& j) const {
  const JobRec& t = j.sequence ? *j.sequence : j;
  int64_t n = int64_t(j.pending.size());
  if (t.status.params.max_workers > 0) n = std::min(n, std::max<int64_t>(0, t.status.params.max_workers - t.live));
  const int64_t cap = share_of(t.status.params.owner).max_workers;
  if (cap > 0) {
    const auto live = live_by_owner.find(t.status.params.owner);
    n = std::min(n, std::max<int64_t>(0, cap - (live == live_by_owner.end() ? 0 : live->second)));
  }
  return n;
}

void FarmState::go_live(const LeaseRec& l) {
  if (live_leases.insert(l.lease.id).second) count_live(l.lease.job, +1);
}

void FarmState::end_lease(LeaseRec& l, LeaseState to) {
  l.state = to;
  if (live_leases.erase(l.lease.id)) count_live(l.lease.job, -1);
  changes.touch_lease(l.lease.id);
}

int FarmState::revoke_leases(JobRec& j) {
  int revoked = 0;
  for (auto it = live_leases.begin(); it != live_leases.end();) {
    LeaseRec& l = leases.at(*it);
    ++it;  // end_lease erases l's entry
    if (l.lease.job != j.status.id) continue;
    end_lease(l, LeaseState::revoked);
    ++revoked;
    TileRec& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == l.lease.id) return_to_pending(j, l.lease.tile);
  }
  return revoked;
}

int FarmState::finish_job(JobRec& j, JobState to, int64_t now, std::optional<std::string> error) {
  const JobRec& shown = top(j);
  const JobState was = state_of(shown);
  dequeue(j);
  j.status.state = to;
  j.status.finished_ms = now;
  j.status.error = std::move(error);
  j.status.reason.reset();
  changes.need_sync();
  touch(j);
  const int revoked = revoke_leases(j);
  settle_dependents(*this, j, now);
  if (&shown != &j && to == JobState::done) note_frame_event(*this, shown, j, now);
  note_job_event(*this, shown, was, now);
  return revoked;
}

}  // namespace tessera::server
