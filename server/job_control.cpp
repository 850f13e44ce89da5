#include "server/job_control.h"

#include "core/image/tiles.h"
#include "server/outbox.h"

#include <algorithm>
#include <memory>
#include <set>
#include <stdexcept>

namespace tessera::server {

namespace {

// True while an upload of one of the job's tiles is being stored.
bool has_merging_tile(const JobRec& j) {
  return std::any_of(j.tiles.begin(), j.tiles.end(), [](const TileRec& t) { return t.state == TileState::merging; });
}

// Sets r.was to the job's state; true when the job has ended, else r's status is not_ended.
template <class R>
bool require_ended(const JobRec& j, R& r) {
  r.was = j.status.state;
  if (is_final(j.status.state)) return true;
  r.status = R::not_ended;
  return false;
}

}  // namespace

void JobControl::check_params(const JobParams& p) {
  const TileGrid grid(p.width, p.height, p.tile_size);  // validates sizes
  if (p.spp == 0) throw std::invalid_argument("spp must be positive");
}

std::string JobControl::add_job(const JobParams& p, const std::string& id_in, int64_t now) {
  const TileGrid grid(p.width, p.height, p.tile_size);
  auto rec = std::make_unique<JobRec>();
  rec->seq = s_.next_seq++;
  rec->status.id = id_in.empty() ? s_.next_id('j') : id_in;
  if (s_.jobs.count(rec->status.id)) throw std::invalid_argument("job id " + rec->status.id + " is already in use");
  check_dependencies(s_, rec->status.id, p.pipeline, {});
  rec->status.params = p;
  rec->status.created_ms = now;
  rec->status.tiles.total = grid.count();
  rec->tiles.resize(size_t(grid.count()));
  s_.changes.need_sync();  // the client is told the job exists
  for (int64_t i = 0; i < grid.count(); ++i) {
    rec->pending.insert(rec->pending.end(), i);
    s_.touch(*rec, i);
  }
  s_.touch(*rec);
  JobRec& j = *rec;
  const std::string id = rec->status.id;
  s_.jobs.emplace(id, std::move(rec));
  hold_new_job(s_, j, now);
  if (!is_held(j.status.state)) s_.enqueue(j);
  try {
    s_.changes.flush(s_);  // here rather than after: a job the store did not take (the disk is full) must not exist
  } catch (...) {
    s_.dequeue(j);
    s_.dependents.remove(id);
    s_.changes.withdraw_job(id);
    s_.jobs.erase(id);  // j is gone with it
    throw;
  }
  s_.work_appeared();
  return id;
}

std::string JobControl::add_sequence(const JobParams& p, const std::vector<FrameParams>& frames,
                                     const std::string& id_in, int64_t now) {
  if (frames.empty()) throw std::invalid_argument("a sequence needs at least one frame");
  auto seq = std::make_unique<JobRec>();
  seq->seq = s_.next_seq++;
  seq->status.id = id_in.empty() ? s_.next_id('j') : id_in;
  const std::string id = seq->status.id;
  if (s_.jobs.count(id)) throw std::invalid_argument("job id " + id + " is already in use");
  {
    std::vector<int64_t> numbers;
    for (const FrameParams& f : frames) numbers.push_back(f.number);
    check_dependencies(s_, id, p.pipeline, numbers);
  }
  seq->status.params = p;
  seq->status.params.width = frames.front().width;
  seq->status.params.height = frames.front().height;
  seq->status.params.spp = frames.front().spp;
  seq->status.params.scene_hash.clear();
  seq->status.created_ms = now;
  seq->status.frames = protocol::FrameCounts{};
  JobRec& sq = *seq;
  std::vector<std::string> added{id};
  s_.jobs.emplace(id, std::move(seq));
  try {
    for (const FrameParams& f : frames) {
      auto rec = std::make_unique<JobRec>();
      rec->seq = s_.next_seq++;
      rec->status.id = frame_job_id(id, f.number);
      if (s_.jobs.count(rec->status.id)) throw std::invalid_argument("job id " + rec->status.id + " is already in use");
      rec->status.params = p;
      rec->status.params.width = f.width;
      rec->status.params.height = f.height;
      rec->status.params.spp = f.spp;
      rec->status.params.scene_hash = f.scene_hash;
      // A frame waits as the sequence says; steps and webhooks are the sequence's.
      rec->status.params.pipeline = protocol::Pipeline{};
      rec->status.params.pipeline.after = frame_dependencies(p.pipeline, f.number);
      rec->status.created_ms = now;
      rec->status.sequence = id;
      rec->status.frame = f.number;
      rec->sequence = &sq;
      const int64_t tiles = TileGrid(f.width, f.height, p.tile_size).count();
      rec->status.tiles.total = tiles;
      rec->tiles.resize(size_t(tiles));
      for (int64_t i = 0; i < tiles; ++i) {
        rec->pending.insert(rec->pending.end(), i);
        s_.touch(*rec, i);
      }
      s_.touch(*rec);
      JobRec& j = *rec;
      added.push_back(rec->status.id);
      s_.jobs.emplace(rec->status.id, std::move(rec));
      sq.frames.push_back(&j);
      hold_new_job(s_, j, now);
      if (!is_held(j.status.state)) s_.enqueue(j);
    }
    note_job_event(s_, sq, JobState::queued, now);  // blocked from the start
    s_.touch(sq);  // after its frames: its stored row counts them
    s_.changes.need_sync();  // the client is told the job exists
    s_.changes.flush(s_);  // as add_job: a sequence the store did not take must not exist
  } catch (...) {
    for (auto it = added.rbegin(); it != added.rend(); ++it) {
      if (JobRec* j = s_.find_job(*it); j && j->sequence) s_.dequeue(*j);
      s_.dependents.remove(*it);
      s_.changes.withdraw_job(*it);
      s_.jobs.erase(*it);
    }
    throw;
  }
  s_.work_appeared();
  return id;
}

CancelResult JobControl::cancel(const std::string& job, int64_t now) {
  return with_job<CancelResult>(job, [&](JobRec& j, CancelResult& r) {
    if (is_final(s_.state_of(j))) {
      r.status = CancelResult::already_ended;
      return;
    }
    if (j.is_sequence()) {
      for (JobRec* f : j.frames)
        if (!is_final(f->status.state)) r.revoked_leases += s_.finish_job(*f, JobState::cancelled, now, std::nullopt);
      s_.touch(j);
    } else {
      r.revoked_leases = s_.finish_job(j, JobState::cancelled, now, std::nullopt);
    }
    r.status = CancelResult::cancelled;
  });
}

RetryResult JobControl::retry(const std::string& job, const std::vector<int64_t>& frames, int64_t now) {
  return with_job<RetryResult>(job, [&](JobRec& j, RetryResult& r) {
    if (!j.is_sequence()) {
      if (!require_ended(j, r)) return;
      if (j.status.state == JobState::done) {
        r.status = RetryResult::done;
        return;
      }
      retry_ended(j, r, now);
      return;
    }
    r.was = s_.state_of(j);
    std::vector<JobRec*> chosen;
    if (frames.empty()) {
      chosen = j.frames;
    } else {
      for (const int64_t n : frames) {
        const auto it = std::lower_bound(j.frames.begin(), j.frames.end(), n,
                                         [](const JobRec* f, int64_t v) { return *f->status.frame < v; });
        if (it == j.frames.end() || *(*it)->status.frame != n) {
          r.status = RetryResult::no_frame;
          r.frame = n;
          return;
        }
        chosen.push_back(*it);
      }
    }
    bool all_done = true;
    for (JobRec* f : chosen) {
      all_done = all_done && f->status.state == JobState::done;
      if (f->status.state == JobState::failed || f->status.state == JobState::cancelled) retry_ended(*f, r, now);
    }
    if (!r.jobs.empty()) {
      s_.touch(j);
      r.status = RetryResult::retried;
    } else {
      r.status = all_done ? RetryResult::done : RetryResult::not_ended;
    }
  });
}

void JobControl::retry_ended(JobRec& j, RetryResult& r, int64_t now) {
  {
    // Leases were revoked when it ended, so its unfinished tiles are pending; only the bookkeeping of its failures
    // goes. It keeps its place in the queue (created_ms and seq).
    j.worker_failures.clear();
    j.worker_last_error.clear();
    for (int64_t i = 0; i < j.status.tiles.total; ++i) {
      TileRec& t = j.tiles[size_t(i)];
      if (t.failures.empty() && t.logs.empty()) continue;
      t.failures.clear();
      t.logs.clear();
      s_.touch(j, i);
    }
    const bool all_done = j.status.tiles.done == j.status.tiles.total;
    j.status.state = all_done || j.status.started_ms ? JobState::running : JobState::queued;
    j.status.finished_ms.reset();
    j.status.error.reset();
    s_.enqueue(j);
    s_.work_appeared();
    s_.changes.need_sync();
    s_.touch(j);
    r.status = RetryResult::retried;
    r.pending += int64_t(j.pending.size());
    r.jobs.push_back(j.status.id);
    settle_retried(s_, j, now);  // waiting again if its own dependencies are not done; its dependents wait for it again
  }
}

RequeueResult JobControl::requeue(const std::string& job, int64_t tile) {
  return with_job<RequeueResult>(job, [&](JobRec& j, RequeueResult& r) {
    r.job_state = j.status.state;
    r.tiles = j.status.tiles.total;
    if (tile < 0 || tile >= j.status.tiles.total) {
      r.status = RequeueResult::no_tile;
      return;
    }
    if (j.status.state == JobState::queued || j.status.state == JobState::done ||
        j.status.state == JobState::cancelled) {
      r.status = RequeueResult::wrong_job_state;
      return;
    }
    TileRec& t = j.tiles[size_t(tile)];
    r.was = t.state;
    if (t.state == TileState::merging || (t.state == TileState::pending && t.failures.empty())) {
      r.status = RequeueResult::wrong_tile_state;
      return;
    }
    if (t.state == TileState::leased) {
      const auto l = s_.leases.find(t.lease);
      if (l != s_.leases.end() && l->second.state == LeaseState::live) s_.end_lease(l->second, LeaseState::revoked);
      r.revoked = true;
    }
    if (t.state == TileState::done) {
      --j.status.tiles.done;
      if (t.unflushed) {
        t.unflushed = false;
        --j.unflushed;
      }
      t.render_ms = -1;
      t.rays = 0;
      t.rendered_by.clear();
      FarmState::forget_tile_log(j, t);
      s_.touch(j);
    }
    t.failures.clear();
    t.logs.clear();
    if (t.state != TileState::pending) s_.return_to_pending(j, tile);
    s_.touch(j, tile);
    s_.changes.need_sync();
    r.status = RequeueResult::requeued;
  });
}

bool JobControl::pause_one(JobRec& j, bool paused) {
  JobStatus& st = j.status;
  const bool allowed =
      paused ? st.state == JobState::queued || st.state == JobState::running : st.state == JobState::paused;
  if (!allowed) return false;
  // A paused job stays in the queue: acquire skips it while its live leases and uploads go on.
  st.state = paused ? JobState::paused : st.started_ms ? JobState::running : JobState::queued;
  if (!paused) s_.work_appeared();
  s_.changes.need_sync();
  s_.touch(j);
  return true;
}

PauseResult JobControl::set_paused(const std::string& job, bool paused) {
  return with_job<PauseResult>(job, [&](JobRec& j, PauseResult& r) {
    r.was = s_.state_of(j);
    bool changed = false;
    if (j.is_sequence()) {
      for (JobRec* f : j.frames) changed = pause_one(*f, paused) || changed;
      if (changed) s_.touch(j);
    } else {
      changed = pause_one(j, paused);
    }
    r.status = changed ? PauseResult::changed : PauseResult::wrong_state;
  });
}

PriorityResult JobControl::set_priority(const std::string& job, int priority) {
  return with_job<PriorityResult>(job, [&](JobRec& j, PriorityResult& r) {
    r.was = s_.state_of(j);
    if (is_final(r.was)) {
      r.status = PriorityResult::ended;
      return;
    }
    // The queue is ordered by priority first: re-key the job (a sequence's frames that have not ended).
    for (JobRec* f : j.is_sequence() ? j.frames : std::vector<JobRec*>{&j}) {
      if (is_final(f->status.state)) continue;
      s_.dequeue(*f);
      f->status.params.priority = priority;
      if (!is_held(f->status.state)) s_.enqueue(*f);
      s_.touch(*f);
    }
    j.status.params.priority = priority;
    s_.touch(j);
    r.status = PriorityResult::changed;
  });
}

RaiseResult JobControl::raise_spp(const std::string& job, uint32_t spp, int64_t now) {
  return with_job<RaiseResult>(job, [&](JobRec& j, RaiseResult& r) {
    r.was = j.status.state;
    if (j.status.state == JobState::failed || j.status.state == JobState::cancelled) {
      r.status = RaiseResult::wrong_state;
      return;
    }
    if (spp <= j.status.params.spp) {
      r.status = RaiseResult::not_higher;
      return;
    }
    if (has_merging_tile(j)) {
      r.status = RaiseResult::merging;
      return;
    }
    r.revoked_leases = s_.revoke_leases(j);
    for (int64_t i = 0; i < j.status.tiles.total; ++i) {
      FarmState::forget_tile_log(j, j.tiles[size_t(i)]);  // its render at the new spp will say its own
      if (j.tiles[size_t(i)].state != TileState::pending) s_.return_to_pending(j, i);
    }
    j.status.tiles.done = 0;
    j.status.params.spp = spp;
    if (j.status.state == JobState::done) {
      j.status.state = JobState::running;
      j.status.finished_ms.reset();
      s_.enqueue(j);
    }
    s_.changes.need_sync();
    s_.touch(j);
    r.status = RaiseResult::raised;
    r.job = s_.snapshot(j, now);
  });
}

PurgeResult JobControl::purge(const std::string& job) {
  return with_job<PurgeResult>(job, [&](JobRec& j, PurgeResult& r) {
    r.was = s_.state_of(j);
    if (!is_final(r.was)) {
      r.status = PurgeResult::not_ended;
      return;
    }
    // The jobs that go: the job, or a sequence with its frames.
    std::set<std::string> gone{job};
    for (const JobRec* f : j.frames) gone.insert(f->status.id);
    // Jobs it holds back would lose what they wait for (or what blocks them).
    r.held = held_dependents(s_, j);
    if (!r.held.empty()) {
      r.status = PurgeResult::holds;
      return;
    }
    // An upload claimed before the job ended is still being stored (finish_result or abandon_result follow).
    for (const std::string& id : gone)
      if (has_merging_tile(*s_.jobs.at(id))) {
        r.status = PurgeResult::busy;
        return;
      }
    // An ended job has no live lease (they were revoked when it ended) and is not in the queue.
    for (auto l = s_.leases.begin(); l != s_.leases.end();) {
      if (gone.count(l->second.lease.job)) {
        s_.changes.forget_lease(l->first);
        l = s_.leases.erase(l);
      } else {
        ++l;
      }
    }
    for (const std::string& id : gone) {
      s_.changes.purge_job(id);
      s_.dependents.remove(id);
      s_.jobs.erase(id);  // j is gone with the last of them
    }
    s_.changes.need_sync();  // the client is told the job is gone
    r.status = PurgeResult::purged;
  });
}

void JobControl::complete_job(const std::string& job, int64_t now) {
  JobRec& j = *s_.jobs.at(job);
  if (started_and_open(j.status) && j.status.tiles.done == j.status.tiles.total)
    s_.finish_job(j, JobState::done, now, std::nullopt);
}

void JobControl::fail_job(const std::string& job, const std::string& error, int64_t now) {
  JobRec& j = *s_.jobs.at(job);
  if (!is_final(j.status.state)) s_.finish_job(j, JobState::failed, now, error);
}

bool JobControl::set_drained(const std::string& worker, bool drained) {
  WorkerRec* w = s_.workers.find(worker);
  if (!w) return false;
  if (w->drained != drained) s_.changes.touch_worker(worker);  // stored: a restart keeps the worker drained
  w->drained = drained;
  if (!drained) s_.work_appeared();
  return true;
}

}  // namespace tessera::server
