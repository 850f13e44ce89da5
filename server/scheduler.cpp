#include "server/scheduler.h"

#include "core/tiles.h"

#include <algorithm>
#include <stdexcept>

namespace tessera::server {

namespace {

// "w-1: text; w-2: text": the error texts of a job's failing workers, for its failure reason.
std::string join_worker_errors(const std::map<std::string, std::string>& errors) {
  std::string out;
  for (const auto& [worker, text] : errors) out += (out.empty() ? "" : "; ") + worker + ": " + text;
  return out;
}

}  // namespace

const char* to_string(JobState s) {
  switch (s) {
    case JobState::queued: return "queued";
    case JobState::running: return "running";
    case JobState::done: return "done";
    case JobState::failed: return "failed";
    case JobState::cancelled: return "cancelled";
  }
  return "unknown";
}

Scheduler::Scheduler(SchedulerConfig config, ClockMs clock) : config_(std::move(config)), clock_(std::move(clock)) {
  if (!clock_) throw std::invalid_argument("scheduler needs a clock");
  if (config_.lease_ms <= 0) throw std::invalid_argument("lease length must be positive");
}

Scheduler::~Scheduler() = default;

std::string Scheduler::next_id(char kind) {
  static_assert(sizeof(uint64_t) == 8);
  return std::string(1, kind) + "-" + (config_.id_tag.empty() ? "" : config_.id_tag + "-") + std::to_string(next_seq_++);
}

std::string Scheduler::new_job_id() {
  std::lock_guard lock(mu_);
  return next_id('j');
}

std::string Scheduler::add_job(const JobParams& p, const std::string& id_in) {
  const TileGrid grid(p.width, p.height, p.tile_size);  // validates sizes
  if (p.spp == 0) throw std::invalid_argument("spp must be positive");
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  auto rec = std::make_unique<JobRec>();
  rec->seq = next_seq_++;
  rec->status.id = id_in.empty() ? next_id('j') : id_in;
  if (jobs_.count(rec->status.id)) throw std::invalid_argument("job id " + rec->status.id + " is already in use");
  rec->status.params = p;
  rec->status.created_ms = now;
  rec->status.tiles.total = grid.count();
  rec->tiles.resize(size_t(grid.count()));
  for (int64_t i = 0; i < grid.count(); ++i) rec->pending.insert(rec->pending.end(), i);
  JobRec* raw = rec.get();
  const std::string id = rec->status.id;
  jobs_.emplace(id, std::move(rec));
  queue_.emplace(QueueKey{-p.priority, now, raw->seq}, raw);
  return id;
}

JobStatus Scheduler::snapshot_locked(const JobRec& j, int64_t) const {
  JobStatus s = j.status;
  s.tiles.pending = int64_t(j.pending.size());
  s.tiles.leased = s.tiles.total - s.tiles.done - s.tiles.pending;
  return s;
}

std::optional<JobStatus> Scheduler::job(const std::string& id) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  const auto it = jobs_.find(id);
  if (it == jobs_.end()) return std::nullopt;
  return snapshot_locked(*it->second, now);
}

std::vector<JobStatus> Scheduler::jobs() {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  std::vector<const JobRec*> recs;
  for (const auto& [id, j] : jobs_) recs.push_back(j.get());
  std::sort(recs.begin(), recs.end(), [](const JobRec* a, const JobRec* b) { return a->seq > b->seq; });
  std::vector<JobStatus> out;
  out.reserve(recs.size());
  for (const JobRec* j : recs) out.push_back(snapshot_locked(*j, now));
  return out;
}

std::string Scheduler::register_worker(const std::string& name) {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  const std::string id = next_id('w');
  workers_.emplace(id, name);
  return id;
}

bool Scheduler::has_worker(const std::string& id) {
  std::lock_guard lock(mu_);
  return workers_.count(id) > 0;
}

AcquireResult Scheduler::acquire(const std::string& worker) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  AcquireResult r;
  if (!workers_.count(worker)) {
    r.status = AcquireResult::unknown_worker;
    return r;
  }
  for (auto& [key, j] : queue_) {
    if (j->pending.empty()) continue;
    const auto wf = j->worker_failures.find(worker);
    if (wf != j->worker_failures.end() && wf->second >= config_.worker_failure_limit) continue;
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
    j->tiles[size_t(tile)].state = TileState::leased;
    j->tiles[size_t(tile)].lease = rec.lease.id;
    if (j->status.state == JobState::queued) {
      j->status.state = JobState::running;
      j->status.started_ms = now;
    }
    live_leases_.insert(rec.lease.id);
    r.status = AcquireResult::granted;
    r.lease = rec.lease;
    leases_.emplace(rec.lease.id, std::move(rec));
    return r;
  }
  r.status = AcquireResult::no_work;
  return r;
}

HeartbeatResult Scheduler::heartbeat(const std::string& lease, uint64_t rays) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  HeartbeatResult r;
  const auto it = leases_.find(lease);
  if (it == leases_.end()) return r;
  if (it->second.state != LeaseState::live) {
    r.status = HeartbeatResult::gone;
    return r;
  }
  it->second.lease.deadline_ms = now + config_.lease_ms;
  if (rays) {
    jobs_.at(it->second.lease.job)->status.rays += rays;
    rays_ += rays;
  }
  r.status = HeartbeatResult::ok;
  r.deadline_ms = it->second.lease.deadline_ms;
  return r;
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
  *job_out = &j;
  *lease_out = &it->second;
  if (j.status.state == JobState::cancelled || j.status.state == JobState::failed) {
    c.status = ResultClaim::discarded;
    return c;
  }
  const TileState ts = j.tiles[size_t(l.tile)].state;
  c.status = (ts == TileState::done || ts == TileState::merging) ? ResultClaim::duplicate : ResultClaim::proceed;
  return c;
}

ResultClaim Scheduler::check_result(const std::string& lease) {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  JobRec* j = nullptr;
  LeaseRec* l = nullptr;
  return claim_view_locked(lease, &j, &l);
}

ResultClaim Scheduler::claim_result(const std::string& lease) {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  JobRec* j = nullptr;
  LeaseRec* l = nullptr;
  ResultClaim c = claim_view_locked(lease, &j, &l);
  if (c.status != ResultClaim::proceed) return c;
  Tile& t = j->tiles[size_t(c.tile)];
  if (t.state == TileState::leased && t.lease != lease) {
    // Another worker holds the tile (this lease expired and it was re-leased): its work is no longer needed.
    const auto other = leases_.find(t.lease);
    if (other != leases_.end() && other->second.state == LeaseState::live) end_lease_locked(other->second, LeaseState::revoked);
  }
  if (t.state == TileState::pending) j->pending.erase(c.tile);
  if (l->state == LeaseState::live) end_lease_locked(*l, LeaseState::completed);
  t.state = TileState::merging;
  t.lease = lease;
  return c;
}

FinishResult Scheduler::finish_result(const std::string& lease, uint64_t rays) {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  FinishResult r;
  const auto it = leases_.find(lease);
  if (it == leases_.end()) throw std::logic_error("finish_result: unknown lease " + lease);
  JobRec& j = *jobs_.at(it->second.lease.job);
  Tile& t = j.tiles[size_t(it->second.lease.tile)];
  if (t.state != TileState::merging || t.lease != lease)
    throw std::logic_error("finish_result: tile " + std::to_string(it->second.lease.tile) + " of " + j.status.id +
                           " is not claimed by lease " + lease);
  t.state = TileState::done;
  t.lease.clear();
  ++j.status.tiles.done;
  ++tiles_rendered_;
  j.status.rays += rays;
  rays_ += rays;
  const std::string& w = it->second.lease.worker;
  if (std::find(j.status.workers.begin(), j.status.workers.end(), w) == j.status.workers.end()) j.status.workers.push_back(w);
  r.last = j.status.state == JobState::running && j.status.tiles.done == j.status.tiles.total;
  return r;
}

void Scheduler::abandon_result(const std::string& lease) {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  const auto it = leases_.find(lease);
  if (it == leases_.end()) return;
  JobRec& j = *jobs_.at(it->second.lease.job);
  Tile& t = j.tiles[size_t(it->second.lease.tile)];
  if (t.state != TileState::merging || t.lease != lease) return;
  t.state = TileState::pending;
  t.lease.clear();
  j.pending.insert(it->second.lease.tile);
}

FailResult Scheduler::fail(const std::string& lease, const std::string& error) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  FailResult r;
  const auto it = leases_.find(lease);
  if (it == leases_.end()) return r;
  r.status = FailResult::recorded;
  LeaseRec& l = it->second;
  JobRec& j = *jobs_.at(l.lease.job);
  Tile& t = j.tiles[size_t(l.lease.tile)];
  // Only a lease that was live (or expired before the report arrived) can fail, and only once; a report on an ended
  // job or a finished tile changes nothing.
  if (l.state != LeaseState::live && l.state != LeaseState::expired) return r;
  if (is_final(j.status.state) || t.state == TileState::done || t.state == TileState::merging) {
    if (l.state == LeaseState::live) end_lease_locked(l, LeaseState::failed);
    return r;
  }
  const bool was_live = l.state == LeaseState::live;
  end_lease_locked(l, LeaseState::failed);
  if (was_live && t.lease == lease) {
    t.state = TileState::pending;
    t.lease.clear();
    j.pending.insert(l.lease.tile);
  }
  const std::string& w = l.lease.worker;
  t.failures[w] = error;
  const int n = ++j.worker_failures[w];
  j.worker_last_error[w] = error;
  r.blocklisted = n == config_.worker_failure_limit;
  if (int(t.failures.size()) >= config_.tile_failure_workers) {
    finish_job_locked(j, JobState::failed, now,
                      "tile " + std::to_string(l.lease.tile) + " failed on " + std::to_string(t.failures.size()) +
                          " workers: " + join_worker_errors(t.failures));
    r.job_failed = true;
    return r;
  }
  // Failures spread over several tiles can blocklist every worker before any one tile fails on enough of them; the
  // job could then never finish, so it fails, with each worker's last error.
  const bool all_blocklisted = std::all_of(workers_.begin(), workers_.end(), [&](const auto& wk) {
    const auto f = j.worker_failures.find(wk.first);
    return f != j.worker_failures.end() && f->second >= config_.worker_failure_limit;
  });
  if (all_blocklisted) {
    finish_job_locked(j, JobState::failed, now,
                      "every registered worker (" + std::to_string(workers_.size()) + ") failed " +
                          std::to_string(config_.worker_failure_limit) + " tiles of this job and is blocklisted for it: " +
                          join_worker_errors(j.worker_last_error));
    r.job_failed = true;
  }
  return r;
}

bool Scheduler::release(const std::string& lease) {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  const auto it = leases_.find(lease);
  if (it == leases_.end()) return false;
  LeaseRec& l = it->second;
  if (l.state != LeaseState::live) return true;
  end_lease_locked(l, LeaseState::released);
  JobRec& j = *jobs_.at(l.lease.job);
  Tile& t = j.tiles[size_t(l.lease.tile)];
  if (t.state == TileState::leased && t.lease == lease) {
    t.state = TileState::pending;
    t.lease.clear();
    j.pending.insert(l.lease.tile);
  }
  return true;
}

CancelResult Scheduler::cancel(const std::string& job) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  CancelResult r;
  const auto it = jobs_.find(job);
  if (it == jobs_.end()) return r;
  if (is_final(it->second->status.state)) {
    r.status = CancelResult::already_ended;
    return r;
  }
  const size_t before = live_leases_.size();
  finish_job_locked(*it->second, JobState::cancelled, now, std::nullopt);
  r.revoked_leases = int(before - live_leases_.size());
  r.status = CancelResult::cancelled;
  return r;
}

void Scheduler::complete_job(const std::string& job) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  JobRec& j = *jobs_.at(job);
  if (j.status.state != JobState::running || j.status.tiles.done != j.status.tiles.total) return;
  finish_job_locked(j, JobState::done, now, std::nullopt);
}

void Scheduler::fail_job(const std::string& job, const std::string& error) {
  std::lock_guard lock(mu_);
  const int64_t now = clock_();
  expire_locked(now);
  JobRec& j = *jobs_.at(job);
  if (is_final(j.status.state)) return;
  finish_job_locked(j, JobState::failed, now, error);
}

void Scheduler::expire() {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
}

SchedulerCounters Scheduler::counters() {
  std::lock_guard lock(mu_);
  expire_locked(clock_());
  SchedulerCounters c;
  for (JobState s : {JobState::queued, JobState::running, JobState::done, JobState::failed, JobState::cancelled}) c.jobs[s] = 0;
  for (const auto& [id, j] : jobs_) ++c.jobs[j->status.state];
  c.tiles_rendered = tiles_rendered_;
  c.lease_expiries = lease_expiries_;
  c.rays = rays_;
  c.workers = int64_t(workers_.size());
  c.active_leases = int64_t(live_leases_.size());
  return c;
}

void Scheduler::expire_locked(int64_t now) {
  for (auto it = live_leases_.begin(); it != live_leases_.end();) {
    LeaseRec& l = leases_.at(*it);
    ++it;  // end_lease_locked erases l's entry
    if (now <= l.lease.deadline_ms) continue;
    end_lease_locked(l, LeaseState::expired);
    ++lease_expiries_;
    JobRec& j = *jobs_.at(l.lease.job);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == l.lease.id) {
      t.state = TileState::pending;
      t.lease.clear();
      j.pending.insert(l.lease.tile);
    }
  }
}

void Scheduler::end_lease_locked(LeaseRec& l, LeaseState to) {
  l.state = to;
  live_leases_.erase(l.lease.id);
}

void Scheduler::finish_job_locked(JobRec& j, JobState to, int64_t now, std::optional<std::string> error) {
  queue_.erase(QueueKey{-j.status.params.priority, j.status.created_ms, j.seq});
  j.status.state = to;
  j.status.finished_ms = now;
  j.status.error = std::move(error);
  for (auto it = live_leases_.begin(); it != live_leases_.end();) {
    LeaseRec& l = leases_.at(*it);
    ++it;
    if (l.lease.job != j.status.id) continue;
    end_lease_locked(l, LeaseState::revoked);
    Tile& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == l.lease.id) {
      t.state = TileState::pending;
      t.lease.clear();
      j.pending.insert(l.lease.tile);
    }
  }
}

}  // namespace tessera::server
