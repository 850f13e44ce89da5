#include "server/job_control.h"

#include "core/image/tiles.h"

#include <algorithm>
#include <memory>
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
  s_.enqueue(j);
  try {
    s_.changes.flush(s_);  // here rather than after: a job the store did not take (the disk is full) must not exist
  } catch (...) {
    s_.dequeue(j);
    s_.changes.withdraw_job(id);
    s_.jobs.erase(id);  // j is gone with it
    throw;
  }
  s_.work_appeared();
  return id;
}

CancelResult JobControl::cancel(const std::string& job, int64_t now) {
  return with_job<CancelResult>(job, [&](JobRec& j, CancelResult& r) {
    if (is_final(j.status.state)) {
      r.status = CancelResult::already_ended;
      return;
    }
    r.revoked_leases = s_.finish_job(j, JobState::cancelled, now, std::nullopt);
    r.status = CancelResult::cancelled;
  });
}

RetryResult JobControl::retry(const std::string& job) {
  return with_job<RetryResult>(job, [&](JobRec& j, RetryResult& r) {
    if (!require_ended(j, r)) return;
    if (j.status.state == JobState::done) {
      r.status = RetryResult::done;
      return;
    }
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
    r.pending = int64_t(j.pending.size());
  });
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

PauseResult JobControl::set_paused(const std::string& job, bool paused) {
  return with_job<PauseResult>(job, [&](JobRec& j, PauseResult& r) {
    JobStatus& st = j.status;
    r.was = st.state;
    const bool allowed =
        paused ? st.state == JobState::queued || st.state == JobState::running : st.state == JobState::paused;
    if (!allowed) {
      r.status = PauseResult::wrong_state;
      return;
    }
    // A paused job stays in the queue: acquire skips it while its live leases and uploads go on.
    st.state = paused ? JobState::paused : st.started_ms ? JobState::running : JobState::queued;
    if (!paused) s_.work_appeared();
    s_.changes.need_sync();
    s_.touch(j);
    r.status = PauseResult::changed;
  });
}

PriorityResult JobControl::set_priority(const std::string& job, int priority) {
  return with_job<PriorityResult>(job, [&](JobRec& j, PriorityResult& r) {
    r.was = j.status.state;
    if (is_final(j.status.state)) {
      r.status = PriorityResult::ended;
      return;
    }
    // The queue is ordered by priority first: re-key the job.
    s_.dequeue(j);
    j.status.params.priority = priority;
    s_.enqueue(j);
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
    for (int64_t i = 0; i < j.status.tiles.total; ++i)
      if (j.tiles[size_t(i)].state != TileState::pending) s_.return_to_pending(j, i);
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
    if (!require_ended(j, r)) return;
    // An upload claimed before the job ended is still being stored (finish_result or abandon_result follow).
    if (has_merging_tile(j)) {
      r.status = PurgeResult::busy;
      return;
    }
    // An ended job has no live lease (they were revoked when it ended) and is not in the queue.
    for (auto l = s_.leases.begin(); l != s_.leases.end();) {
      if (l->second.lease.job == job) {
        s_.changes.forget_lease(l->first);
        l = s_.leases.erase(l);
      } else {
        ++l;
      }
    }
    s_.changes.purge_job(job);
    s_.jobs.erase(job);  // j is gone with it
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
