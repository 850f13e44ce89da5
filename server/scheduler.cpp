#include "server/scheduler.h"

#include <utility>

#include "core/image/tiles.h"

#include <spdlog/spdlog.h>

#include <cstdint>
#include <algorithm>
#include <limits>
#include <stdexcept>
#include <type_traits>

namespace tessera::server {

namespace {

// "w-1: text; w-2: text": the error texts of a job's failing workers, for its failure reason.
std::string join_worker_errors(const std::map<std::string, std::string>& errors) {
  std::string out;
  for (const auto& [worker, text] : errors) out += (out.empty() ? "" : "; ") + worker + ": " + text;
  return out;
}

// A job that has started and not ended: its last upload completes it.
bool started_and_open(const JobStatus& s) {
  return s.state == JobState::running || (s.state == JobState::paused && s.started_ms);
}

}  // namespace

Scheduler::Scheduler(SchedulerConfig config, ClockMs clock) : config_(std::move(config)), clock_(std::move(clock)) {
  if (!clock_) throw std::invalid_argument("scheduler needs a clock");
  if (config_.lease_ms <= 0) throw std::invalid_argument("lease length must be positive");
  if (config_.worker_failure_limit < 1) throw std::invalid_argument("the worker failure limit must be at least 1");
  if (config_.tile_failure_workers < 1) throw std::invalid_argument("the tile failure workers must be at least 1");
}

Scheduler::Scheduler(SchedulerConfig config, ClockMs clock, SchedulerStore& store)
    : Scheduler(std::move(config), std::move(clock)) {
  store_ = &store;
  std::lock_guard lock(mu_);
  restore_locked(store.load(), clock_());
  flush_locked();
}

Scheduler::~Scheduler() = default;

// Runs one operation under the lock: expired leases are reclaimed first, and everything the operation (and the
// reclaiming) changed goes to the store as one batch before the lock is released (with store_now false, the changes
// wait for the next operation that stores: for changes a restart may safely forget).
template <class F>
auto Scheduler::transact(F&& f, bool store_now, std::function<void()> durable) {
  std::unique_lock lock(mu_);
  const int64_t now = clock_();
  using R = std::invoke_result_t<F&, int64_t>;
  std::optional<R> r;
  try {
    expire_locked(now);
    r.emplace(f(now));
  } catch (...) {
    try {
      flush_locked();  // what changed before the failure still has to be stored
    } catch (...) {
    }
    throw;
  }
  if (store_now) flush_locked();
  const bool due = std::exchange(sync_due_, false);
  lock.unlock();
  // Outside the lock: other operations go on while the disk catches up. With `durable`, the caller does not wait
  // either: the store runs it once the flush is done.
  if (due && durable) store_->sync_async(std::move(durable));
  else if (due) store_->sync();
  else if (durable) durable();
  return std::move(*r);
}

// Runs f(job record, result, now) in one transaction (transact) when `job` is known; for an unknown job the result is
// R as default-constructed (whose status says so).
template <class R, class F>
R Scheduler::with_job(const std::string& job, F&& f) {
  return transact([&](int64_t now) {
    R r;
    if (const auto it = jobs_.find(job); it != jobs_.end()) f(*it->second, r, now);
    return r;
  });
}

bool Scheduler::has_merging_tile(const JobRec& j) {
  return std::any_of(j.tiles.begin(), j.tiles.end(), [](const Tile& t) { return t.state == TileState::merging; });
}

void Scheduler::after_sync(std::function<void()> then) {
  if (store_) store_->sync_async(std::move(then));
  else then();
}

void Scheduler::flush_locked() {
  const CounterRow counters{next_seq_, tiles_rendered_, lease_expiries_, rays_};
  auto pixels = std::move(done_pixels_);
  done_pixels_.reset();
  if (!store_) {
    dirty_jobs_.clear();
    new_job_workers_.clear();
    dirty_tiles_.clear();
    dirty_leases_.clear();
    new_workers_.clear();
    purged_jobs_.clear();
    sync_needed_ = false;
    return;
  }
  if (dirty_jobs_.empty() && new_job_workers_.empty() && dirty_tiles_.empty() && dirty_leases_.empty() &&
      new_workers_.empty() && purged_jobs_.empty() && counters == flushed_counters_)
    return;
  SchedulerChanges c;
  c.counters = counters;
  for (const std::string& id : dirty_jobs_) {
    const auto it = jobs_.find(id);
    if (it == jobs_.end()) continue;
    JobRec& j = *it->second;
    // The job's workers (up to every worker of the farm) go as rows of their own (new_job_workers_), not copied here.
    std::vector<std::string> workers;
    workers.swap(j.status.workers);
    c.jobs.push_back(JobRow{snapshot_locked(j, 0), j.seq, j.worker_failures, j.worker_last_error});
    workers.swap(j.status.workers);
  }
  for (const JobWorkerRow& w : new_job_workers_)
    if (jobs_.count(w.job)) c.job_workers.push_back(w);
  for (const auto& key : dirty_tiles_) {
    const auto it = jobs_.find(key.first);
    if (it == jobs_.end()) continue;
    const Tile& t = it->second->tiles[size_t(key.second)];
    TileRow row{key.first, key.second, t.state, t.lease, t.failures, std::nullopt, t.logs, t.attempts, t.render_ms, t.rays,
                t.rendered_by};
    if (pixels && pixels->first == key && !pixels->second.empty()) row.pixels = pixels->second;
    c.tiles.push_back(std::move(row));
  }
  for (const std::string& id : dirty_leases_) {
    const auto it = leases_.find(id);
    if (it != leases_.end()) c.leases.push_back(LeaseRow{it->second.lease, it->second.state, it->second.granted_ms});
  }
  for (const std::string& id : new_workers_) {
    const auto it = workers_.find(id);
    if (it != workers_.end()) c.workers.push_back(WorkerRow{id, it->second.name, it->second.drained});
  }
  c.purged_jobs.assign(purged_jobs_.begin(), purged_jobs_.end());
  // On failure the dirty sets stay, so the next operation writes these rows again.
  store_->apply(c);
  if (std::exchange(sync_needed_, false)) sync_due_ = true;
  dirty_jobs_.clear();
  new_job_workers_.clear();
  dirty_tiles_.clear();
  dirty_leases_.clear();
  new_workers_.clear();
  purged_jobs_.clear();
  flushed_counters_ = counters;
}

void Scheduler::restore_locked(SchedulerSnapshot snap, int64_t now) {
  next_expiry_check_ms_ = 0;  // restored leases get new deadlines: the next operation looks at them all
  next_seq_ = std::max<uint64_t>(1, snap.counters.next_seq);
  tiles_rendered_ = snap.counters.tiles_rendered;
  lease_expiries_ = snap.counters.lease_expiries;
  rays_ = snap.counters.rays;
  flushed_counters_ = snap.counters;
  for (const WorkerRow& w : snap.workers) {
    WorkerRec& rec = workers_[w.id] = WorkerRec{w.name, now};  // downtime counts against nobody
    rec.drained = w.drained;
  }
  for (JobRow& row : snap.jobs) {
    auto rec = std::make_unique<JobRec>();
    const JobParams& p = row.status.params;
    const TileGrid grid(p.width, p.height, p.tile_size);
    rec->status = std::move(row.status);
    rec->worker_set.insert(rec->status.workers.begin(), rec->status.workers.end());
    rec->status.tiles = TileCounts{grid.count(), 0, 0, 0};
    rec->seq = row.seq;
    rec->worker_failures = std::move(row.worker_failures);
    rec->worker_last_error = std::move(row.worker_last_error);
    rec->tiles.resize(size_t(grid.count()));
    const std::string id = rec->status.id;
    jobs_.emplace(id, std::move(rec));
  }
  for (TileRow& row : snap.tiles) {
    const auto it = jobs_.find(row.job);
    if (it == jobs_.end() || row.index < 0 || row.index >= it->second->status.tiles.total)
      throw std::invalid_argument("stored tile " + std::to_string(row.index) + " of job " + row.job +
                                  " belongs to no stored job");
    Tile& t = it->second->tiles[size_t(row.index)];
    t.state = row.state;
    t.lease = std::move(row.lease);
    t.failures = std::move(row.failures);
    t.logs = std::move(row.logs);
    t.attempts = row.attempts;
    t.render_ms = row.render_ms;
    t.rays = row.rays;
    t.rendered_by = std::move(row.rendered_by);
  }
  for (LeaseRow& row : snap.leases) {
    const auto jt = jobs_.find(row.lease.job);
    if (jt == jobs_.end()) throw std::invalid_argument("stored lease " + row.lease.id + " belongs to no stored job");
    const JobParams& p = jt->second->status.params;
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
      const Tile& t = jt->second->tiles[size_t(rec.lease.tile)];
      if (is_final(jt->second->status.state) || t.state != TileState::leased || t.lease != rec.lease.id) {
        rec.state = LeaseState::revoked;  // cannot happen in a consistent store; repaired rather than trusted
        dirty_leases_.insert(rec.lease.id);
      } else {
        rec.lease.deadline_ms = now + config_.lease_ms;  // the worker gets a whole lease to come back
        live_leases_.insert(rec.lease.id);
      }
    }
    leases_.emplace(rec.lease.id, std::move(rec));
  }
  for (auto& [id, j] : jobs_) {
    for (int64_t i = 0; i < j->status.tiles.total; ++i) {
      Tile& t = j->tiles[size_t(i)];
      if (t.state == TileState::merging || (t.state == TileState::leased && !live_leases_.count(t.lease))) {
        // An upload that was being stored was never acknowledged: its worker sends it again, or another renders it.
        t.state = TileState::pending;
        t.lease.clear();
        touch_tile(*j, i);
      }
      if (t.state == TileState::done) ++j->status.tiles.done;
      if (t.state == TileState::pending) j->pending.insert(j->pending.end(), i);
    }
    if (!is_final(j->status.state)) queue_.emplace(QueueKey{-j->status.params.priority, j->status.created_ms, j->seq}, j.get());
  }
}

std::string Scheduler::next_id(char kind) {
  return std::string(1, kind) + "-" + (config_.id_tag.empty() ? "" : config_.id_tag + "-") + std::to_string(next_seq_++);
}

std::string Scheduler::new_job_id() {
  return transact([&](int64_t) { return next_id('j'); });
}

std::string Scheduler::add_job(const JobParams& p, const std::string& id_in) {
  const TileGrid grid(p.width, p.height, p.tile_size);  // validates sizes
  if (p.spp == 0) throw std::invalid_argument("spp must be positive");
  return transact([&](int64_t now) {
    auto rec = std::make_unique<JobRec>();
    rec->seq = next_seq_++;
    rec->status.id = id_in.empty() ? next_id('j') : id_in;
    if (jobs_.count(rec->status.id)) throw std::invalid_argument("job id " + rec->status.id + " is already in use");
    rec->status.params = p;
    rec->status.created_ms = now;
    rec->status.tiles.total = grid.count();
    rec->tiles.resize(size_t(grid.count()));
    sync_needed_ = true;  // the client is told the job exists
    for (int64_t i = 0; i < grid.count(); ++i) {
      rec->pending.insert(rec->pending.end(), i);
      touch_tile(*rec, i);
    }
    touch_job(*rec);
    JobRec* raw = rec.get();
    const std::string id = rec->status.id;
    jobs_.emplace(id, std::move(rec));
    queue_.emplace(QueueKey{-p.priority, now, raw->seq}, raw);
    work_appeared_locked();
    return id;
  });
}

JobStatus Scheduler::snapshot_locked(const JobRec& j, int64_t now) const {
  JobStatus s = j.status;
  s.tiles.done -= j.unflushed;  // not durable yet: counted with the tiles in progress
  s.tiles.pending = int64_t(j.pending.size());
  s.tiles.leased = s.tiles.total - s.tiles.done - s.tiles.pending;
  if (s.started_ms) s.render_seconds = double(s.finished_ms.value_or(now) - *s.started_ms) / 1000.0;
  return s;
}

std::optional<JobStatus> Scheduler::job(const std::string& id) {
  return transact([&](int64_t now) -> std::optional<JobStatus> {
    const auto it = jobs_.find(id);
    if (it == jobs_.end()) return std::nullopt;
    return snapshot_locked(*it->second, now);
  });
}

std::optional<protocol::TileList> Scheduler::tiles(const std::string& job) {
  return transact([&](int64_t) -> std::optional<protocol::TileList> {
    const auto it = jobs_.find(job);
    if (it == jobs_.end()) return std::nullopt;
    const JobParams& p = it->second->status.params;
    const TileGrid grid(p.width, p.height, p.tile_size);
    const auto name_of = [&](const std::string& worker) {
      const auto w = workers_.find(worker);
      return w == workers_.end() ? std::string() : w->second.name;
    };
    protocol::TileList out{job, {}};
    out.tiles.reserve(it->second->tiles.size());
    for (size_t i = 0; i < it->second->tiles.size(); ++i) {
      const Tile& t = it->second->tiles[i];
      protocol::TileInfo v;
      v.index = int64_t(i);
      v.window = grid.window(v.index);
      v.state = t.unflushed ? to_string(TileState::merging) : to_string(t.state);
      v.attempts = t.attempts;
      if (t.render_ms >= 0) v.render_seconds = double(t.render_ms) / 1000.0;
      v.rays = t.rays;
      const auto l = t.state == TileState::pending || t.state == TileState::done ? leases_.end() : leases_.find(t.lease);
      if (l != leases_.end()) {
        v.worker = l->second.lease.worker;
        v.worker_name = name_of(*v.worker);
      }
      if (t.state == TileState::done && !t.rendered_by.empty()) {
        v.rendered_by = t.rendered_by;
        v.rendered_by_name = name_of(t.rendered_by);
      }
      for (const auto& [worker, error] : t.failures) {
        const auto log = t.logs.find(worker);
        v.failures.push_back({worker, name_of(worker), error, log == t.logs.end() ? std::vector<std::string>{} : log->second});
      }
      out.tiles.push_back(std::move(v));
    }
    return out;
  });
}

std::vector<JobStatus> Scheduler::jobs() {
  return transact([&](int64_t now) {
    std::vector<const JobRec*> recs;
    for (const auto& [id, j] : jobs_) recs.push_back(j.get());
    std::sort(recs.begin(), recs.end(), [](const JobRec* a, const JobRec* b) { return a->seq > b->seq; });
    std::vector<JobStatus> out;
    out.reserve(recs.size());
    for (const JobRec* j : recs) out.push_back(snapshot_locked(*j, now));
    return out;
  });
}

JobPage Scheduler::jobs(const JobQuery& q) {
  return transact([&](int64_t now) {
    std::vector<const JobRec*> recs;
    for (const auto& [id, j] : jobs_)
      if ((q.states.empty() || q.states.count(j->status.state)) && (!q.after || j->seq < *q.after)) recs.push_back(j.get());
    std::sort(recs.begin(), recs.end(), [](const JobRec* a, const JobRec* b) { return a->seq > b->seq; });
    JobPage page;
    if (q.limit > 0 && recs.size() > q.limit) {
      recs.resize(q.limit);
      page.more = true;
    }
    for (const JobRec* j : recs) {
      page.jobs.push_back(snapshot_locked(*j, now));
      page.seqs.push_back(j->seq);
    }
    return page;
  });
}

std::optional<uint64_t> Scheduler::job_seq(const std::string& id) {
  return transact([&](int64_t) -> std::optional<uint64_t> {
    const auto it = jobs_.find(id);
    if (it == jobs_.end()) return std::nullopt;
    return it->second->seq;
  });
}

std::string Scheduler::register_worker(const std::string& name, int64_t threads) {
  return transact([&](int64_t now) {
    const std::string id = next_id('w');
    workers_.emplace(id, WorkerRec{name, now, threads});
    new_workers_.insert(id);
    return id;
  });
}

bool Scheduler::has_worker(const std::string& id) {
  std::lock_guard lock(mu_);
  return workers_.count(id) > 0;
}

void Scheduler::seen_locked(const std::string& worker, int64_t now) {
  const auto it = workers_.find(worker);
  if (it != workers_.end()) it->second.last_seen_ms = std::max(it->second.last_seen_ms, now);
}

std::vector<protocol::WorkerInfo> Scheduler::workers() {
  return transact([&](int64_t now) {
    // Each worker's lease and blocklists, gathered in one pass over the live leases and the jobs (not one per worker).
    std::map<std::string_view, const Lease*> holding;
    for (const std::string& lid : live_leases_) {
      const Lease& l = leases_.at(lid).lease;
      holding.emplace(l.worker, &l);  // the first in id order, as worker_info_locked picks it
    }
    std::map<std::string_view, std::vector<std::string>> blocklists;
    for (const auto& [jid, j] : jobs_) {
      if (is_final(j->status.state)) continue;
      for (const auto& [worker, failures] : j->worker_failures)
        if (failures >= config_.worker_failure_limit) blocklists[worker].push_back(jid);
    }
    std::vector<protocol::WorkerInfo> out;
    out.reserve(workers_.size());
    for (const auto& [id, w] : workers_) {
      const auto h = holding.find(id);
      const auto b = blocklists.find(id);
      out.push_back(worker_info_locked(id, w, now, h == holding.end() ? nullptr : h->second,
                                       b == blocklists.end() ? std::vector<std::string>{} : std::move(b->second)));
    }
    return out;
  });
}

std::optional<protocol::WorkerInfo> Scheduler::set_drained(const std::string& worker, bool drained) {
  return transact([&](int64_t now) -> std::optional<protocol::WorkerInfo> {
    const auto it = workers_.find(worker);
    if (it == workers_.end()) return std::nullopt;
    if (it->second.drained != drained) new_workers_.insert(worker);  // stored: a restart keeps the worker drained
    it->second.drained = drained;
    if (!drained) work_appeared_locked();
    return worker_info_locked(it->first, it->second, now);
  });
}

int64_t Scheduler::gone_ms() const { return config_.worker_gone_ms > 0 ? config_.worker_gone_ms : 3 * config_.lease_ms; }

protocol::WorkerInfo Scheduler::worker_info_locked(const std::string& id, const WorkerRec& w, int64_t now) const {
  const Lease* holding = nullptr;
  for (const std::string& lid : live_leases_) {
    const Lease& l = leases_.at(lid).lease;
    if (l.worker != id) continue;
    holding = &l;
    break;
  }
  std::vector<std::string> blocklisted_for;
  for (const auto& [jid, j] : jobs_)
    if (!is_final(j->status.state) && blocklisted_locked(*j, id)) blocklisted_for.push_back(jid);
  return worker_info_locked(id, w, now, holding, std::move(blocklisted_for));
}

protocol::WorkerInfo Scheduler::worker_info_locked(const std::string& id, const WorkerRec& w, int64_t now,
                                                   const Lease* holding, std::vector<std::string> blocklisted_for) const {
  protocol::WorkerInfo info;
  info.id = id;
  info.name = w.name;
  info.threads = w.threads;
  info.tiles_done = w.tiles_done;
  info.rays = w.rays;
  info.render_seconds = double(w.render_ms) / 1000.0;
  info.last_seen_ms = w.last_seen_ms;
  if (holding) {
    info.job = holding->job;
    info.tile = holding->tile;
  }
  info.blocklisted_for = std::move(blocklisted_for);
  using protocol::WorkerState;
  info.state = now - w.last_seen_ms > gone_ms() ? WorkerState::offline
               : w.drained                      ? WorkerState::draining
               : info.job                       ? WorkerState::rendering
                                                : WorkerState::idle;
  return info;
}

bool Scheduler::all_present_blocklisted_locked(const JobRec& j, int64_t now, size_t* present) const {
  const int64_t gone = gone_ms();
  *present = 0;
  for (const auto& [id, w] : workers_) {
    if (now - w.last_seen_ms > gone) continue;  // died or left: it will not take this job's tiles
    ++*present;
    if (!blocklisted_locked(j, id)) return false;
  }
  return *present > 0;
}

bool Scheduler::fail_if_all_blocklisted_locked(JobRec& j, int64_t now) {
  size_t present = 0;
  if (is_final(j.status.state) || !all_present_blocklisted_locked(j, now, &present)) return false;
  // Failures spread over several tiles can blocklist every worker before any one tile fails on enough of them; the
  // job could then never finish, so it fails, with each worker's last error.
  finish_job_locked(j, JobState::failed, now,
                    "every registered worker that is still present (" + std::to_string(present) + ") failed " +
                        std::to_string(config_.worker_failure_limit) + " tiles of this job and is blocklisted for it: " +
                        join_worker_errors(j.worker_last_error));
  return true;
}

AcquireResult Scheduler::acquire(const std::string& worker) {
  return transact([&](int64_t now) {
    AcquireResult r;
    if (!workers_.count(worker)) {
      r.status = AcquireResult::unknown_worker;
      return r;
    }
    seen_locked(worker, now);
    if (workers_.at(worker).drained) {  // it keeps polling and hears "no work" until undrained
      r.status = AcquireResult::no_work;
      return r;
    }
    std::vector<JobRec*> stuck;  // jobs this worker may not take: fail them if no present worker may
    for (auto& [key, j] : queue_) {
      if (j->pending.empty() || j->status.state == JobState::paused) continue;
      if (blocklisted_locked(*j, worker)) {
        stuck.push_back(j);
        continue;
      }
      const int64_t tile = *j->pending.begin();
      j->pending.erase(j->pending.begin());
      const JobParams& p = j->status.params;
      LeaseRec rec;
      rec.lease.id = next_id('l');
      rec.lease.job = j->status.id;
      rec.lease.worker = worker;
      rec.lease.tile = tile;
      rec.lease.window = TileGrid(p.width, p.height, p.tile_size).window(tile);
      rec.lease.spp = p.spp;
      rec.lease.seed = p.seed;
      rec.lease.scene_hash = p.scene_hash;
      rec.lease.deadline_ms = now + config_.lease_ms;
      rec.granted_ms = now;
      j->tiles[size_t(tile)].state = TileState::leased;
      j->tiles[size_t(tile)].lease = rec.lease.id;
      ++j->tiles[size_t(tile)].attempts;
      touch_tile(*j, tile);
      if (j->status.state == JobState::queued) {
        j->status.state = JobState::running;
        j->status.started_ms = now;
        touch_job(*j);
      }
      live_leases_.insert(rec.lease.id);
      dirty_leases_.insert(rec.lease.id);
      next_expiry_check_ms_ = std::min(next_expiry_check_ms_, expiry_check_ms(rec));
      r.status = AcquireResult::granted;
      r.lease = rec.lease;
      r.job_state = j->status.state;
      leases_.emplace(rec.lease.id, std::move(rec));
      break;
    }
    for (JobRec* j : stuck) fail_if_all_blocklisted_locked(*j, now);  // after the loop: this erases from queue_
    if (r.status != AcquireResult::granted) r.status = AcquireResult::no_work;
    return r;
  });
}

int64_t Scheduler::leasable_tiles(const std::string& worker) {
  std::lock_guard lock(mu_);
  const auto w = workers_.find(worker);
  if (w == workers_.end() || w->second.drained) return 0;
  int64_t n = 0;
  for (const auto& [key, j] : queue_)
    if (j->status.state != JobState::paused && !blocklisted_locked(*j, worker)) n += int64_t(j->pending.size());
  return n;
}

bool Scheduler::blocklisted_locked(const JobRec& j, const std::string& worker) const {
  const auto wf = j.worker_failures.find(worker);
  return wf != j.worker_failures.end() && wf->second >= config_.worker_failure_limit;
}

HeartbeatResult Scheduler::heartbeat(const std::string& lease, uint64_t rays) {
  return transact([&](int64_t now) {
    HeartbeatResult r;
    const auto it = leases_.find(lease);
    if (it == leases_.end()) return r;
    seen_locked(it->second.lease.worker, now);
    if (it->second.state != LeaseState::live) {
      r.status = HeartbeatResult::gone;
      return r;
    }
    // The new deadline is not stored: a restarted coordinator gives every live lease a fresh one anyway.
    it->second.lease.deadline_ms = now + config_.lease_ms;
    it->second.rays += rays;
    if (rays) {
      JobRec& j = *jobs_.at(it->second.lease.job);
      j.status.rays += rays;
      rays_ += rays;
      touch_job(j);
    }
    r.status = HeartbeatResult::ok;
    r.deadline_ms = it->second.lease.deadline_ms;
    return r;
  });
}

ResultClaim Scheduler::claim_view_locked(const std::string& lease, JobRec** job_out, LeaseRec** lease_out) {
  ResultClaim c;
  const auto it = leases_.find(lease);
  if (it == leases_.end()) return c;
  JobRec& j = *jobs_.at(it->second.lease.job);
  const Lease& l = it->second.lease;
  c.job = l.job;
  c.worker = l.worker;
  c.tile = l.tile;
  c.window = l.window;
  c.width = j.status.params.width;
  c.height = j.status.params.height;
  c.spp = j.status.params.spp;
  *job_out = &j;
  *lease_out = &it->second;
  if (j.status.state == JobState::cancelled || j.status.state == JobState::failed || l.spp != c.spp) {
    c.status = ResultClaim::discarded;
    return c;
  }
  const TileState ts = j.tiles[size_t(l.tile)].state;
  c.status = (ts == TileState::done || ts == TileState::merging) ? ResultClaim::duplicate : ResultClaim::proceed;
  return c;
}

ResultClaim Scheduler::check_result(const std::string& lease) {
  return transact([&](int64_t) {
    JobRec* j = nullptr;
    LeaseRec* l = nullptr;
    return claim_view_locked(lease, &j, &l);
  });
}

ResultClaim Scheduler::claim_result(const std::string& lease) {
  return transact([&](int64_t now) {
    JobRec* j = nullptr;
    LeaseRec* l = nullptr;
    ResultClaim c = claim_view_locked(lease, &j, &l);
    if (c.status == ResultClaim::unknown) return c;
    seen_locked(c.worker, now);
    if (c.status != ResultClaim::proceed) return c;
    Tile& t = j->tiles[size_t(c.tile)];
    if (t.state == TileState::leased && t.lease != lease) {
      // Another worker holds the tile (this lease expired and it was re-leased): its work is no longer needed.
      const auto other = leases_.find(t.lease);
      if (other != leases_.end() && other->second.state == LeaseState::live) end_lease_locked(other->second, LeaseState::revoked);
    }
    if (t.state == TileState::pending) j->pending.erase(c.tile);
    l->live_at_claim = l->state == LeaseState::live;
    if (l->state == LeaseState::live) end_lease_locked(*l, LeaseState::completed);
    t.state = TileState::merging;
    t.lease = lease;
    touch_tile(*j, c.tile);
    return c;
  }, /*store_now=*/false);  // stored with finish_result: a restart before it finds the tile as it was, which is the same
}

FinishResult Scheduler::finish_result(const std::string& lease, uint64_t rays, std::string_view pixels) {
  std::pair<std::string, int64_t> tile;
  const FinishResult r = transact([&](int64_t now) { return finish_result_locked(lease, rays, pixels, now, &tile); });
  flushed(tile.first, tile.second);  // transact returned after the flush
  return r;
}

void Scheduler::finish_result(const std::string& lease, uint64_t rays, std::string_view pixels,
                              std::function<void(FinishResult)> durable) {
  // Set under the lock, before the store can run the continuation.
  auto result = std::make_shared<std::pair<FinishResult, std::pair<std::string, int64_t>>>();
  transact([&](int64_t now) { return result->first = finish_result_locked(lease, rays, pixels, now, &result->second); },
           /*store_now=*/true, [this, result, durable = std::move(durable)] {
             flushed(result->second.first, result->second.second);
             durable(result->first);
           });
}

void Scheduler::flushed(const std::string& job, int64_t tile) {
  std::lock_guard lock(mu_);
  const auto it = jobs_.find(job);
  if (it == jobs_.end()) return;  // purged meanwhile
  Tile& t = it->second->tiles[size_t(tile)];
  if (!t.unflushed) return;
  t.unflushed = false;
  --it->second->unflushed;
}

FinishResult Scheduler::finish_result_locked(const std::string& lease, uint64_t rays, std::string_view pixels,
                                             int64_t now, std::pair<std::string, int64_t>* tile_key) {
  {
    FinishResult r;
    const auto it = leases_.find(lease);
    if (it == leases_.end()) throw std::logic_error("finish_result: unknown lease " + lease);
    JobRec& j = *jobs_.at(it->second.lease.job);
    const int64_t tile = it->second.lease.tile;
    Tile& t = j.tiles[size_t(tile)];
    if (t.state != TileState::merging || t.lease != lease)
      throw std::logic_error("finish_result: tile " + std::to_string(tile) + " of " + j.status.id +
                             " is not claimed by lease " + lease);
    const Tile tile_before = t;
    const uint64_t rays_before = rays_, rendered_before = tiles_rendered_, job_rays_before = j.status.rays;
    t.state = TileState::done;
    t.lease.clear();
    t.render_ms = std::max<int64_t>(0, now - it->second.granted_ms);
    t.rays = it->second.rays + rays;
    t.rendered_by = it->second.lease.worker;
    ++j.status.tiles.done;
    ++tiles_rendered_;
    j.status.rays += rays;
    rays_ += rays;
    const std::string& w = it->second.lease.worker;
    const auto wr = workers_.find(w);
    if (wr != workers_.end()) {
      ++wr->second.tiles_done;
      wr->second.rays += t.rays;
      wr->second.render_ms += t.render_ms;
    }
    const bool new_worker = j.worker_set.insert(w).second;
    if (new_worker) {
      new_job_workers_.push_back(JobWorkerRow{j.status.id, int64_t(j.status.workers.size()), w});
      j.status.workers.push_back(w);
    }
    touch_tile(j, tile);
    touch_job(j);
    done_pixels_.emplace(std::make_pair(j.status.id, tile), pixels);
    sync_needed_ = true;  // the worker is told its result is safe
    try {
      flush_locked();  // here rather than after: a tile the store did not take must not look done
    } catch (...) {
      if (wr != workers_.end()) {  // before t is restored: its rays and time are what was added
        --wr->second.tiles_done;
        wr->second.rays -= t.rays;
        wr->second.render_ms -= t.render_ms;
      }
      t = tile_before;
      --j.status.tiles.done;
      j.status.rays = job_rays_before;
      if (new_worker) {
        j.status.workers.pop_back();
        j.worker_set.erase(w);
        new_job_workers_.pop_back();
      }
      rays_ = rays_before;
      tiles_rendered_ = rendered_before;
      throw;
    }
    // Done and committed, but shown as being merged until the flush that makes it durable has returned.
    t.unflushed = true;
    ++j.unflushed;
    *tile_key = {j.status.id, tile};
    r.last = started_and_open(j.status) && j.status.tiles.done == j.status.tiles.total;
    return r;
  }
}

void Scheduler::abandon_result(const std::string& lease) {
  transact([&](int64_t now) {
    const auto it = leases_.find(lease);
    if (it == leases_.end()) return 0;
    LeaseRec& l = it->second;
    JobRec& j = *jobs_.at(l.lease.job);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    if (t.state != TileState::merging || t.lease != lease) return 0;
    if (!l.live_at_claim || is_final(j.status.state)) {
      return_to_pending_locked(j, l.lease.tile);
      return 0;
    }
    // The merge failed on the coordinator's side and the worker retries the upload: the tile stays its, under the
    // lease it held (live again for a lease length), instead of going to the next worker that asks.
    t.state = TileState::leased;
    l.state = LeaseState::live;
    l.lease.deadline_ms = now + config_.lease_ms;
    live_leases_.insert(lease);
    next_expiry_check_ms_ = std::min(next_expiry_check_ms_, expiry_check_ms(l));
    touch_lease(l);
    touch_tile(j, l.lease.tile);
    return 0;
  });
}

FailResult Scheduler::fail(const std::string& lease, const std::string& error, const std::vector<std::string>& log) {
  return transact([&](int64_t now) {
    FailResult r;
    const auto it = leases_.find(lease);
    if (it == leases_.end()) return r;
    r.status = FailResult::recorded;
    LeaseRec& l = it->second;
    JobRec& j = *jobs_.at(l.lease.job);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    seen_locked(l.lease.worker, now);
    // Only a lease that was live (or expired before the report arrived) can fail, and only once; a report on an ended
    // job or a finished tile changes nothing.
    if (l.state != LeaseState::live && l.state != LeaseState::expired) return r;
    if (is_final(j.status.state) || t.state == TileState::done || t.state == TileState::merging) {
      if (l.state == LeaseState::live) end_lease_locked(l, LeaseState::failed);
      return r;
    }
    return record_failure_locked(j, l, error, log, now);
  });
}

FailResult Scheduler::record_failure_locked(JobRec& j, LeaseRec& l, const std::string& error,
                                            std::vector<std::string> log, int64_t now) {
  FailResult r;
  r.status = FailResult::recorded;
  Tile& t = j.tiles[size_t(l.lease.tile)];
  const bool was_live = l.state == LeaseState::live;
  end_lease_locked(l, LeaseState::failed);
  if (was_live && t.lease == l.lease.id) return_to_pending_locked(j, l.lease.tile);
  const std::string& w = l.lease.worker;
  t.failures[w] = error;
  if (log.empty()) t.logs.erase(w);
  else t.logs[w] = std::move(log);
  const int n = ++j.worker_failures[w];
  j.worker_last_error[w] = error;
  touch_tile(j, l.lease.tile);
  touch_job(j);
  r.blocklisted = n == config_.worker_failure_limit;
  if (int(t.failures.size()) >= config_.tile_failure_workers) {
    finish_job_locked(j, JobState::failed, now,
                      "tile " + std::to_string(l.lease.tile) + " failed on " + std::to_string(t.failures.size()) +
                          " workers: " + join_worker_errors(t.failures));
    r.job_failed = true;
    return r;
  }
  r.job_failed = fail_if_all_blocklisted_locked(j, now);
  return r;
}

bool Scheduler::release(const std::string& lease) {
  return transact([&](int64_t) {
    const auto it = leases_.find(lease);
    if (it == leases_.end()) return false;
    LeaseRec& l = it->second;
    if (l.state != LeaseState::live) return true;
    end_lease_locked(l, LeaseState::released);
    JobRec& j = *jobs_.at(l.lease.job);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == lease) return_to_pending_locked(j, l.lease.tile);
    return true;
  });
}

RetryResult Scheduler::retry(const std::string& job) {
  return with_job<RetryResult>(job, [&](JobRec& j, RetryResult& r, int64_t) {
    r.was = j.status.state;
    if (!is_final(j.status.state)) {
      r.status = RetryResult::not_ended;
      return;
    }
    if (j.status.state == JobState::done) {
      r.status = RetryResult::done;
      return;
    }
    // Leases were revoked when it ended, so its unfinished tiles are pending; only the bookkeeping of its failures
    // goes. It keeps its place in the queue (created_ms and seq).
    j.worker_failures.clear();
    j.worker_last_error.clear();
    for (int64_t i = 0; i < j.status.tiles.total; ++i) {
      Tile& t = j.tiles[size_t(i)];
      if (t.failures.empty() && t.logs.empty()) continue;
      t.failures.clear();
      t.logs.clear();
      touch_tile(j, i);
    }
    const bool all_done = j.status.tiles.done == j.status.tiles.total;
    j.status.state = all_done || j.status.started_ms ? JobState::running : JobState::queued;
    j.status.finished_ms.reset();
    j.status.error.reset();
    queue_.emplace(QueueKey{-j.status.params.priority, j.status.created_ms, j.seq}, &j);
    work_appeared_locked();
    sync_needed_ = true;
    touch_job(j);
    r.status = RetryResult::retried;
    r.pending = int64_t(j.pending.size());
  });
}

RequeueResult Scheduler::requeue(const std::string& job, int64_t tile) {
  return with_job<RequeueResult>(job, [&](JobRec& j, RequeueResult& r, int64_t) {
    r.job_state = j.status.state;
    r.tiles = j.status.tiles.total;
    if (tile < 0 || tile >= j.status.tiles.total) {
      r.status = RequeueResult::no_tile;
      return;
    }
    if (j.status.state == JobState::queued || j.status.state == JobState::done || j.status.state == JobState::cancelled) {
      r.status = RequeueResult::wrong_job_state;
      return;
    }
    Tile& t = j.tiles[size_t(tile)];
    r.was = t.state;
    if (t.state == TileState::merging || (t.state == TileState::pending && t.failures.empty())) {
      r.status = RequeueResult::wrong_tile_state;
      return;
    }
    if (t.state == TileState::leased) {
      const auto l = leases_.find(t.lease);
      if (l != leases_.end() && l->second.state == LeaseState::live) end_lease_locked(l->second, LeaseState::revoked);
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
      touch_job(j);
    }
    t.failures.clear();
    t.logs.clear();
    if (t.state != TileState::pending) return_to_pending_locked(j, tile);
    touch_tile(j, tile);
    sync_needed_ = true;
    r.status = RequeueResult::requeued;
  });
}

PauseResult Scheduler::pause(const std::string& job) { return set_paused(job, true); }

PauseResult Scheduler::resume(const std::string& job) { return set_paused(job, false); }

PauseResult Scheduler::set_paused(const std::string& job, bool paused) {
  return with_job<PauseResult>(job, [&](JobRec& j, PauseResult& r, int64_t) {
    JobStatus& st = j.status;
    r.was = st.state;
    const bool allowed =
        paused ? st.state == JobState::queued || st.state == JobState::running : st.state == JobState::paused;
    if (!allowed) {
      r.status = PauseResult::wrong_state;
      return;
    }
    // A paused job stays in queue_: acquire skips it while its live leases and uploads go on.
    st.state = paused ? JobState::paused : st.started_ms ? JobState::running : JobState::queued;
    if (!paused) work_appeared_locked();
    sync_needed_ = true;
    touch_job(j);
    r.status = PauseResult::changed;
  });
}

PriorityResult Scheduler::set_priority(const std::string& job, int priority) {
  return with_job<PriorityResult>(job, [&](JobRec& j, PriorityResult& r, int64_t) {
    r.was = j.status.state;
    if (is_final(j.status.state)) {
      r.status = PriorityResult::ended;
      return;
    }
    // The queue is ordered by (-priority, created_ms, seq): re-key the job.
    queue_.erase(QueueKey{-j.status.params.priority, j.status.created_ms, j.seq});
    j.status.params.priority = priority;
    queue_.emplace(QueueKey{-priority, j.status.created_ms, j.seq}, &j);
    touch_job(j);
    r.status = PriorityResult::changed;
  });
}

CancelResult Scheduler::cancel(const std::string& job) {
  return with_job<CancelResult>(job, [&](JobRec& j, CancelResult& r, int64_t now) {
    if (is_final(j.status.state)) {
      r.status = CancelResult::already_ended;
      return;
    }
    const size_t before = live_leases_.size();
    finish_job_locked(j, JobState::cancelled, now, std::nullopt);
    r.revoked_leases = int(before - live_leases_.size());
    r.status = CancelResult::cancelled;
  });
}

RaiseResult Scheduler::raise_spp(const std::string& job, uint32_t spp) {
  return with_job<RaiseResult>(job, [&](JobRec& j, RaiseResult& r, int64_t now) {
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
    for (auto l = live_leases_.begin(); l != live_leases_.end();) {
      LeaseRec& rec = leases_.at(*l);
      ++l;  // end_lease_locked erases rec's entry
      if (rec.lease.job != job) continue;
      end_lease_locked(rec, LeaseState::revoked);
      ++r.revoked_leases;
    }
    for (int64_t i = 0; i < j.status.tiles.total; ++i)
      if (j.tiles[size_t(i)].state != TileState::pending) return_to_pending_locked(j, i);
    j.status.tiles.done = 0;
    j.status.params.spp = spp;
    if (j.status.state == JobState::done) {
      j.status.state = JobState::running;
      j.status.finished_ms.reset();
      queue_.emplace(QueueKey{-j.status.params.priority, j.status.created_ms, j.seq}, &j);
    }
    sync_needed_ = true;
    touch_job(j);
    r.status = RaiseResult::raised;
    r.job = snapshot_locked(j, now);
  });
}

PurgeResult Scheduler::purge(const std::string& job) {
  return with_job<PurgeResult>(job, [&](JobRec& j, PurgeResult& r, int64_t) {
    r.was = j.status.state;
    if (!is_final(j.status.state)) {
      r.status = PurgeResult::not_ended;
      return;
    }
    // An upload claimed before the job ended is still being stored (finish_result or abandon_result follow).
    if (has_merging_tile(j)) {
      r.status = PurgeResult::busy;
      return;
    }
    // An ended job has no live lease (they were revoked when it ended) and is not in queue_.
    for (auto l = leases_.begin(); l != leases_.end();) {
      if (l->second.lease.job == job) {
        dirty_leases_.erase(l->first);
        l = leases_.erase(l);
      } else {
        ++l;
      }
    }
    dirty_jobs_.erase(job);
    for (auto t = dirty_tiles_.lower_bound({job, INT64_MIN}); t != dirty_tiles_.end() && t->first == job;)
      t = dirty_tiles_.erase(t);
    jobs_.erase(job);  // j is gone with it
    purged_jobs_.insert(job);
    sync_needed_ = true;  // the client is told the job is gone
    r.status = PurgeResult::purged;
  });
}

void Scheduler::complete_job(const std::string& job) {
  transact([&](int64_t now) {
    JobRec& j = *jobs_.at(job);
    if (!started_and_open(j.status) || j.status.tiles.done != j.status.tiles.total) return 0;
    finish_job_locked(j, JobState::done, now, std::nullopt);
    return 0;
  });
}

void Scheduler::fail_job(const std::string& job, const std::string& error) {
  transact([&](int64_t now) {
    JobRec& j = *jobs_.at(job);
    if (!is_final(j.status.state)) finish_job_locked(j, JobState::failed, now, error);
    return 0;
  });
}

void Scheduler::expire() {
  transact([](int64_t) { return 0; });
}

SchedulerCounters Scheduler::counters() {
  return transact([&](int64_t) {
    SchedulerCounters c;
    for (JobState s : protocol::kAllJobStates) c.jobs[s] = 0;
    for (const auto& [id, j] : jobs_) ++c.jobs[j->status.state];
    c.tiles_rendered = tiles_rendered_;
    c.lease_expiries = lease_expiries_;
    c.rays = rays_;
    c.workers = int64_t(workers_.size());
    c.active_leases = int64_t(live_leases_.size());
    return c;
  });
}

std::vector<std::string> Scheduler::unfinalized_jobs() {
  return transact([&](int64_t) {
    std::vector<std::string> out;
    for (const auto& [key, j] : queue_)
      if (started_and_open(j->status) && j->status.tiles.done == j->status.tiles.total) out.push_back(j->status.id);
    return out;
  });
}

void Scheduler::return_to_pending_locked(JobRec& j, int64_t tile) {
  Tile& t = j.tiles[size_t(tile)];
  if (t.unflushed) {  // no longer done: its flush has nothing left to show
    t.unflushed = false;
    --j.unflushed;
  }
  t.state = TileState::pending;
  t.lease.clear();
  j.pending.insert(tile);
  touch_tile(j, tile);
  work_appeared_locked();
}

int64_t Scheduler::expiry_check_ms(const LeaseRec& l) const {
  return std::min(l.lease.deadline_ms, l.granted_ms + jobs_.at(l.lease.job)->status.params.tile_timeout_seconds * 1000) + 1;
}

void Scheduler::expire_locked(int64_t now) {
  if (now < next_expiry_check_ms_) return;  // nothing can have expired: every operation would otherwise scan them all
  next_expiry_check_ms_ = std::numeric_limits<int64_t>::max();
  std::vector<std::string> timed_out;  // handled after the loop: failing a job ends other leases of live_leases_
  for (auto it = live_leases_.begin(); it != live_leases_.end();) {
    LeaseRec& l = leases_.at(*it);
    ++it;  // end_lease_locked erases l's entry
    if (now <= l.lease.deadline_ms) {
      if (now - l.granted_ms > jobs_.at(l.lease.job)->status.params.tile_timeout_seconds * 1000)
        timed_out.push_back(l.lease.id);
      else
        next_expiry_check_ms_ = std::min(next_expiry_check_ms_, expiry_check_ms(l));
      continue;
    }
    end_lease_locked(l, LeaseState::expired);
    ++lease_expiries_;
    spdlog::info("job {} tile {} worker {}: lease {} expired", l.lease.job, l.lease.tile, l.lease.worker, l.lease.id);
    JobRec& j = *jobs_.at(l.lease.job);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == l.lease.id) return_to_pending_locked(j, l.lease.tile);
  }
  for (const std::string& id : timed_out) {
    LeaseRec& l = leases_.at(id);
    if (l.state != LeaseState::live) continue;  // revoked when an earlier timeout failed its job
    JobRec& j = *jobs_.at(l.lease.job);
    const std::string error = "tile timed out after " + std::to_string(j.status.params.tile_timeout_seconds) + " s";
    spdlog::warn("job {} tile {} worker {}: lease {} revoked: {}", l.lease.job, l.lease.tile, l.lease.worker, l.lease.id,
                 error);
    const FailResult f = record_failure_locked(j, l, error, {}, now);
    if (f.job_failed) spdlog::warn("job {}: failed: {}", j.status.id, j.status.error.value_or(""));
  }
}

void Scheduler::end_lease_locked(LeaseRec& l, LeaseState to) {
  l.state = to;
  live_leases_.erase(l.lease.id);
  touch_lease(l);
}

void Scheduler::finish_job_locked(JobRec& j, JobState to, int64_t now, std::optional<std::string> error) {
  queue_.erase(QueueKey{-j.status.params.priority, j.status.created_ms, j.seq});
  j.status.state = to;
  j.status.finished_ms = now;
  j.status.error = std::move(error);
  sync_needed_ = true;
  touch_job(j);
  for (auto it = live_leases_.begin(); it != live_leases_.end();) {
    LeaseRec& l = leases_.at(*it);
    ++it;
    if (l.lease.job != j.status.id) continue;
    end_lease_locked(l, LeaseState::revoked);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == l.lease.id) return_to_pending_locked(j, l.lease.tile);
  }
}

}  // namespace tessera::server
