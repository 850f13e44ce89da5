#include "server/change_log.h"

#include "core/image/tiles.h"
#include "server/farm_state.h"

#include <algorithm>
#include <climits>
#include <memory>
#include <stdexcept>

namespace tessera::server {

void ChangeLog::purge_job(const std::string& job) {
  withdraw_job(job);
  purged_jobs_.insert(job);
}

void ChangeLog::withdraw_job(const std::string& job) {
  jobs_.erase(job);
  std::erase_if(outbox_, [&](const OutboxRow& r) { return r.job == job; });
  for (auto t = tiles_.lower_bound({job, INT64_MIN}); t != tiles_.end() && t->first == job;) t = tiles_.erase(t);
}

void ChangeLog::clear() {
  jobs_.clear();
  job_workers_.clear();
  tiles_.clear();
  leases_.clear();
  workers_.clear();
  forgotten_workers_.clear();
  purged_jobs_.clear();
  outbox_.clear();
}

void ChangeLog::flush(FarmState& s) {
  const CounterRow counters = s.counter_row();
  auto pixels = std::move(done_pixels_);
  done_pixels_.reset();
  if (!store_) {
    clear();
    sync_needed_ = false;
    return;
  }
  if (jobs_.empty() && job_workers_.empty() && tiles_.empty() && leases_.empty() && workers_.empty() &&
      forgotten_workers_.empty() && purged_jobs_.empty() && outbox_.empty() && counters == flushed_counters_)
    return;
  SchedulerChanges c;
  c.counters = counters;
  for (const std::string& id : jobs_) {
    const auto it = s.jobs.find(id);
    if (it == s.jobs.end()) continue;
    JobRec& j = *it->second;
    // The job's workers (up to every worker of the farm) go as rows of their own (job_workers_), not copied here.
    std::vector<std::string> workers;
    workers.swap(j.status.workers);
    c.jobs.push_back(JobRow{s.snapshot(j, 0), j.seq, j.worker_failures, j.worker_last_error});
    workers.swap(j.status.workers);
  }
  for (const JobWorkerRow& w : job_workers_)
    if (s.jobs.count(w.job)) c.job_workers.push_back(w);
  for (const auto& key : tiles_) {
    const auto it = s.jobs.find(key.first);
    if (it == s.jobs.end()) continue;
    const TileRec& t = it->second->tiles[size_t(key.second)];
    TileRow row{key.first, key.second, t.state,       t.lease, t.failures,    std::nullopt, t.logs,
                t.attempts, t.render_ms,  t.rays, t.rendered_by, t.log, t.log_not_kept};
    if (pixels && pixels->first == key && !pixels->second.empty()) row.pixels = pixels->second;
    c.tiles.push_back(std::move(row));
  }
  for (const std::string& id : leases_) {
    const auto it = s.leases.find(id);
    if (it != s.leases.end()) c.leases.push_back(LeaseRow{it->second.lease, it->second.state, it->second.granted_ms});
  }
  for (const std::string& id : workers_)
    if (const WorkerRec* w = s.workers.find(id)) c.workers.push_back(WorkerRow{id, w->name, w->drained, w->secret_hash, w->tags});
  c.forgotten_workers.assign(forgotten_workers_.begin(), forgotten_workers_.end());
  c.purged_jobs.assign(purged_jobs_.begin(), purged_jobs_.end());
  c.outbox = outbox_;
  // On failure the sets stay, so the next flush writes these rows again.
  store_->apply(c);
  if (std::exchange(sync_needed_, false)) sync_due_ = true;
  clear();
  flushed_counters_ = counters;
}

void restore(FarmState& s, SchedulerSnapshot snap, int64_t now) {
  s.next_seq = std::max<uint64_t>(1, snap.counters.next_seq);
  s.tiles_rendered = snap.counters.tiles_rendered;
  s.lease_expiries = snap.counters.lease_expiries;
  s.rays = snap.counters.rays;
  s.changes.loaded(snap.counters);
  for (const WorkerRow& w : snap.workers) {
    WorkerRec rec{w.name, now};  // downtime counts against nobody
    rec.drained = w.drained;
    rec.secret_hash = w.secret_hash;
    rec.tags = w.tags;
    s.workers.add(w.id, std::move(rec));
  }
  for (JobRow& row : snap.jobs) {
    auto rec = std::make_unique<JobRec>();
    const JobParams& p = row.status.params;
    // A sequence has no tiles of its own (its frames are jobs).
    const int64_t tiles = row.status.frames ? 0 : TileGrid(p.width, p.height, p.tile_size).count();
    rec->status = std::move(row.status);
    rec->worker_set.insert(rec->status.workers.begin(), rec->status.workers.end());
    rec->status.tiles = TileCounts{tiles, 0, 0, 0};
    rec->seq = row.seq;
    rec->worker_failures = std::move(row.worker_failures);
    rec->worker_last_error = std::move(row.worker_last_error);
    rec->tiles.resize(size_t(tiles));
    const std::string id = rec->status.id;
    s.jobs.emplace(id, std::move(rec));
  }
  // Each frame joins its sequence, in frame order (rows come in submission order, which is frame order).
  for (auto& [id, j] : s.jobs) {
    if (!j->status.sequence) continue;
    JobRec* seq = s.find_job(*j->status.sequence);
    if (!seq || !seq->is_sequence())
      throw std::invalid_argument("stored job " + id + " is a frame of " + *j->status.sequence + ", which is no stored sequence");
    j->sequence = seq;
    seq->frames.push_back(j.get());
  }
  for (auto& [id, j] : s.jobs)
    std::sort(j->frames.begin(), j->frames.end(),
              [](const JobRec* a, const JobRec* b) { return *a->status.frame < *b->status.frame; });
  for (TileRow& row : snap.tiles) {
    JobRec* j = s.find_job(row.job);
    if (!j || row.index < 0 || row.index >= j->status.tiles.total)
      throw std::invalid_argument("stored tile " + std::to_string(row.index) + " of job " + row.job +
                                  " belongs to no stored job");
    TileRec& t = j->tiles[size_t(row.index)];
    t.state = row.state;
    t.lease = std::move(row.lease);
    t.failures = std::move(row.failures);
    t.logs = std::move(row.logs);
    t.attempts = row.attempts;
    t.render_ms = row.render_ms;
    t.rays = row.rays;
    t.rendered_by = std::move(row.rendered_by);
    t.log = std::move(row.log);
    t.log_not_kept = row.log_not_kept;
    for (const std::string& line : t.log) j->log_bytes += int64_t(line.size());
    if (t.log_not_kept) ++j->logs_not_kept;
  }
  for (LeaseRow& row : snap.leases) {
    const JobRec* j = s.find_job(row.lease.job);
    if (!j) throw std::invalid_argument("stored lease " + row.lease.id + " belongs to no stored job");
    const JobParams& p = j->status.params;
    const TileGrid grid(p.width, p.height, p.tile_size);
    if (row.lease.tile < 0 || row.lease.tile >= grid.count())
      throw std::invalid_argument("stored lease " + row.lease.id + " names tile " + std::to_string(row.lease.tile) +
                                  " outside its job");
    row.lease.window = grid.window(row.lease.tile);
    row.lease.spp = p.spp;
    row.lease.seed = p.seed;
    row.lease.scene_hash = p.scene_hash;
    LeaseRec rec{row.lease, row.state, row.granted_ms};
    if (rec.granted_ms <= 0) rec.granted_ms = now;  // stored before grant times were: the timeout counts from now
    if (rec.state == LeaseState::live) {
      const TileRec& t = j->tiles[size_t(rec.lease.tile)];
      if (is_final(j->status.state) || t.state != TileState::leased || t.lease != rec.lease.id) {
        rec.state = LeaseState::revoked;  // cannot happen in a consistent store; repaired rather than trusted
        s.changes.touch_lease(rec.lease.id);
      } else {
        rec.lease.deadline_ms = now + s.config.lease_ms;  // the worker gets a whole lease to come back
        s.go_live(rec);
      }
    }
    s.leases.emplace(rec.lease.id, std::move(rec));
  }
  for (auto& [id, j] : s.jobs) {
    for (int64_t i = 0; i < j->status.tiles.total; ++i) {
      TileRec& t = j->tiles[size_t(i)];
      if (t.state == TileState::merging || (t.state == TileState::leased && !s.live_leases.count(t.lease))) {
        // An upload that was being stored was never acknowledged: its worker sends it again, or another renders it.
        t.state = TileState::pending;
        t.lease.clear();
        s.touch(*j, i);
      }
      if (t.state == TileState::done) ++j->status.tiles.done;
      if (t.state == TileState::pending) j->pending.insert(j->pending.end(), i);
    }
    if (!is_final(j->status.state) && !is_held(j->status.state) && !j->is_sequence()) s.enqueue(*j);
  }
  restore_dependencies(s);
}

}  // namespace tessera::server
