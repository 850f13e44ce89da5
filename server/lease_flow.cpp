#include "server/lease_flow.h"

#include "core/image/tiles.h"
#include "protocol/tags.h"
#include "server/worker_secret.h"

#include <spdlog/spdlog.h>

#include <limits>
#include <stdexcept>

namespace tessera::server {

std::string LeaseFlow::register_worker(const std::string& name, int64_t threads, const std::vector<std::string>& tags,
                                       const std::string& secret_hash, int64_t now) {
  if (s_.config.max_workers > 0 && int64_t(s_.workers.size()) >= s_.config.max_workers) return {};
  const std::string id = s_.next_id('w');
  WorkerRec rec{name, now, threads};
  rec.secret_hash = secret_hash;
  rec.tags = tags;
  s_.workers.add(id, std::move(rec));
  s_.changes.touch_worker(id);
  if (s_.config.worker_retention_ms > 0)  // the first moment forget_workers() may forget it
    next_forget_check_ms_ =
        std::min(next_forget_check_ms_, now + std::max(s_.config.worker_retention_ms, s_.workers.gone_ms()) + 1);
  return id;
}

WorkerCheck LeaseFlow::check_worker(const std::string& worker, std::string_view secret) const {
  const WorkerRec* w = s_.workers.find(worker);
  // A worker stored without a secret (by a build that had none) cannot prove who it is: it registers again.
  if (!w || w->secret_hash.empty()) return WorkerCheck::unknown_worker;
  return worker_secret_matches(w->secret_hash, secret) ? WorkerCheck::ok : WorkerCheck::wrong_secret;
}

WorkerCheck LeaseFlow::check_lease_holder(const std::string& lease, std::string_view secret, std::string* holder) const {
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) return WorkerCheck::unknown_lease;
  *holder = it->second.lease.worker;
  return check_worker(*holder, secret);
}

AcquireResult LeaseFlow::acquire(const std::string& worker, int64_t now) {
  AcquireResult r;
  const WorkerRec* w = s_.workers.find(worker);
  if (!w) {
    r.status = AcquireResult::unknown_worker;
    return r;
  }
  s_.workers.seen(worker, now);
  if (w->drained) {  // it keeps polling and hears "no work" until undrained
    r.status = AcquireResult::no_work;
    return r;
  }
  std::vector<JobRec*> stuck;  // jobs this worker may not take: fail them if no present worker may
  JobRec* const chosen = pick_job(worker, *w, stuck);
  if (JobRec* j = chosen) {
    const int64_t tile = *j->pending.begin();
    j->pending.erase(j->pending.begin());
    const JobParams& p = j->status.params;
    LeaseRec rec;
    rec.lease.id = s_.next_id('l');
    rec.lease.job = j->status.id;
    rec.lease.worker = worker;
    rec.lease.tile = tile;
    rec.lease.window = TileGrid(p.width, p.height, p.tile_size).window(tile);
    rec.lease.spp = p.spp;
    rec.lease.seed = p.seed;
    rec.lease.scene_hash = p.scene_hash;
    rec.lease.deadline_ms = now + s_.config.lease_ms;
    rec.granted_ms = now;
    TileRec& t = j->tiles[size_t(tile)];
    t.state = TileState::leased;
    t.lease = rec.lease.id;
    ++t.attempts;
    s_.touch(*j, tile);
    if (j->status.state == JobState::queued) {
      j->status.state = JobState::running;
      j->status.started_ms = now;
      s_.touch(*j);
    }
    s_.go_live(rec);
    s_.changes.touch_lease(rec.lease.id);
    watch(rec);
    r.status = AcquireResult::granted;
    r.lease = rec.lease;
    r.job_state = j->status.state;
    s_.leases.emplace(rec.lease.id, std::move(rec));
    s_.workers.find(worker)->last_job = j->status.id;
  }
  for (JobRec* j : stuck) s_.fail_if_all_blocklisted(*j, now);  // after the loop: this erases from the queue
  if (r.status != AcquireResult::granted) r.status = AcquireResult::no_work;
  return r;
}

JobRec* LeaseFlow::pick_job(const std::string& worker, const WorkerRec& w, std::vector<JobRec*>& stuck) const {
  // Each owner's first job (in priority, then submission order) this worker may take now.
  struct Candidate {
    JobRec* job = nullptr;
    JobRec* shared = nullptr;  // the first frame, leased in any order, that another worker is on
    bool settled = false;      // found, or the owner is at its cap
  };
  std::map<std::string_view, Candidate> candidates;
  size_t settled = 0;  // owners whose candidate is found (or who are at their cap)
  for (auto& [key, j] : s_.queue) {
    if (settled == s_.queued_by_owner.size()) break;  // every owner with queued jobs has its candidate
    const std::string& owner = j->status.params.owner;
    const auto [it, fresh] = candidates.try_emplace(owner);
    Candidate& c = it->second;
    if (fresh) {
      const OwnerShare& share = s_.share_of(owner);
      const auto live = s_.live_by_owner.find(owner);
      if (share.max_workers > 0 && live != s_.live_by_owner.end() && live->second >= share.max_workers) {
        c.settled = true;  // at the owner's cap: none of its jobs now
        ++settled;
      }
    }
    if (c.settled) continue;
    if (j->pending.empty() || j->status.state == JobState::paused) continue;
    if (!protocol::has_tags(w.tags, j->status.params.require)) continue;
    const JobRec& top = FarmState::top(*j);
    if (top.status.params.max_workers > 0 && top.live >= top.status.params.max_workers) continue;
    if (s_.blocklisted(*j, worker)) {
      stuck.push_back(j);
      continue;
    }
    // A sequence leased in any order keeps each worker on a frame of its own (each scene is loaded by one worker),
    // and shares a frame only when no other is left.
    if (j->sequence && j->status.params.frame_order == protocol::FrameOrder::any &&
        j->pending.size() != j->tiles.size() && w.last_job != j->status.id) {
      if (!c.shared) c.shared = j;
      continue;
    }
    c.job = j;
    c.settled = true;
    ++settled;
  }
  // The owner furthest below its share of the rendering workers (this grant included) gets the lease; ties go to the
  // job first in the queue.
  // The owners sharing the farm: those with a job to lease and those holding leases.
  double weights = 0;
  for (const auto& [owner, c] : candidates)
    if (c.job || c.shared || s_.live_by_owner.count(owner)) weights += s_.share_of(owner).weight;
  for (const auto& [owner, live] : s_.live_by_owner)
    if (!candidates.count(owner)) weights += s_.share_of(owner).weight;
  const double rendering = double(s_.live_leases.size() + 1);
  JobRec* best = nullptr;
  double best_deficit = 0;
  for (const auto& [owner, c] : candidates) {
    JobRec* j = c.job ? c.job : c.shared;
    if (!j) continue;
    const auto live = s_.live_by_owner.find(owner);
    const double deficit = rendering * s_.share_of(owner).weight / weights -
                           double(live == s_.live_by_owner.end() ? 0 : live->second);
    if (!best || deficit > best_deficit ||
        (deficit == best_deficit && FarmState::queue_key(*j) < FarmState::queue_key(*best))) {
      best = j;
      best_deficit = deficit;
    }
  }
  return best;
}

int64_t LeaseFlow::leasable_tiles(const std::string& worker) const {
  const WorkerRec* w = s_.workers.find(worker);
  if (!w || w->drained) return 0;
  int64_t n = 0;
  for (const auto& [key, j] : s_.queue)
    if (j->status.state != JobState::paused && protocol::has_tags(w->tags, j->status.params.require) &&
        !s_.blocklisted(*j, worker))
      n += s_.leasable_now(*j);
  return n;
}

HeartbeatResult LeaseFlow::heartbeat(const std::string& lease, uint64_t rays, int64_t now) {
  HeartbeatResult r;
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) return r;
  s_.workers.seen(it->second.lease.worker, now);
  if (it->second.state != LeaseState::live) {
    r.status = HeartbeatResult::gone;
    return r;
  }
  // The new deadline is not stored: a restarted coordinator gives every live lease a fresh one anyway.
  it->second.lease.deadline_ms = now + s_.config.lease_ms;
  it->second.rays += rays;
  if (rays) {
    JobRec& j = *s_.jobs.at(it->second.lease.job);
    j.status.rays += rays;
    s_.rays += rays;
    s_.touch(j);
  }
  r.status = HeartbeatResult::ok;
  r.deadline_ms = it->second.lease.deadline_ms;
  return r;
}

ResultClaim LeaseFlow::claim_view(const std::string& lease, JobRec** job_out, LeaseRec** lease_out) {
  ResultClaim c;
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) return c;
  JobRec& j = *s_.jobs.at(it->second.lease.job);
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

ResultClaim LeaseFlow::check_result(const std::string& lease) {
  JobRec* j = nullptr;
  LeaseRec* l = nullptr;
  return claim_view(lease, &j, &l);
}

ResultClaim LeaseFlow::claim_result(const std::string& lease, int64_t now) {
  JobRec* j = nullptr;
  LeaseRec* l = nullptr;
  ResultClaim c = claim_view(lease, &j, &l);
  if (c.status == ResultClaim::unknown) return c;
  s_.workers.seen(c.worker, now);
  if (c.status != ResultClaim::proceed) return c;
  TileRec& t = j->tiles[size_t(c.tile)];
  if (t.state == TileState::leased && t.lease != lease) {
    // Another worker holds the tile (this lease expired and it was re-leased): its work is no longer needed.
    const auto other = s_.leases.find(t.lease);
    if (other != s_.leases.end() && other->second.state == LeaseState::live) s_.end_lease(other->second, LeaseState::revoked);
  }
  if (t.state == TileState::pending) j->pending.erase(c.tile);
  l->live_at_claim = l->state == LeaseState::live;
  if (l->state == LeaseState::live) s_.end_lease(*l, LeaseState::completed);
  t.state = TileState::merging;
  t.lease = lease;
  s_.touch(*j, c.tile);
  return c;
}

FinishResult LeaseFlow::finish_result(const std::string& lease, uint64_t rays, std::string_view pixels,
                                      std::vector<std::string> log, int64_t now,
                                      std::pair<std::string, int64_t>* tile_key) {
  FinishResult r;
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) throw std::logic_error("finish_result: unknown lease " + lease);
  JobRec& j = *s_.jobs.at(it->second.lease.job);
  const int64_t tile = it->second.lease.tile;
  TileRec& t = j.tiles[size_t(tile)];
  if (t.state != TileState::merging || t.lease != lease)
    throw std::logic_error("finish_result: tile " + std::to_string(tile) + " of " + j.status.id +
                           " is not claimed by lease " + lease);
  const TileRec tile_before = t;
  const uint64_t rays_before = s_.rays, rendered_before = s_.tiles_rendered, job_rays_before = j.status.rays;
  const int64_t log_bytes_before = j.log_bytes, logs_not_kept_before = j.logs_not_kept;
  t.state = TileState::done;
  t.lease.clear();
  t.render_ms = std::max<int64_t>(0, now - it->second.granted_ms);
  t.rays = it->second.rays + rays;
  t.rendered_by = it->second.lease.worker;
  s_.keep_tile_log(j, t, std::move(log));
  ++j.status.tiles.done;
  ++s_.tiles_rendered;
  j.status.rays += rays;
  s_.rays += rays;
  const std::string& w = it->second.lease.worker;
  s_.workers.credit(w, t.render_ms, t.rays);
  const bool new_worker = j.worker_set.insert(w).second;
  if (new_worker) {
    s_.changes.add_job_worker(JobWorkerRow{j.status.id, int64_t(j.status.workers.size()), w});
    j.status.workers.push_back(w);
  }
  s_.touch(j, tile);
  s_.touch(j);
  s_.changes.set_done_pixels(j.status.id, tile, pixels);
  s_.changes.need_sync();  // the worker is told its result is safe
  try {
    s_.changes.flush(s_);  // here rather than after: a tile the store did not take must not look done
  } catch (...) {
    s_.workers.debit(w, t.render_ms, t.rays);  // before t is restored: its rays and time are what was added
    t = tile_before;
    j.log_bytes = log_bytes_before;
    j.logs_not_kept = logs_not_kept_before;
    --j.status.tiles.done;
    j.status.rays = job_rays_before;
    if (new_worker) {
      j.status.workers.pop_back();
      j.worker_set.erase(w);
      s_.changes.drop_last_job_worker();
    }
    s_.rays = rays_before;
    s_.tiles_rendered = rendered_before;
    throw;
  }
  // Done and committed, but shown as being merged until the flush that makes it durable has returned.
  t.unflushed = true;
  ++j.unflushed;
  *tile_key = {j.status.id, tile};
  r.last = started_and_open(j.status) && j.status.tiles.done == j.status.tiles.total;
  return r;
}

void LeaseFlow::flushed(const std::string& job, int64_t tile) {
  JobRec* j = s_.find_job(job);
  if (!j) return;  // purged meanwhile
  TileRec& t = j->tiles[size_t(tile)];
  if (!t.unflushed) return;
  t.unflushed = false;
  --j->unflushed;
}

void LeaseFlow::abandon_result(const std::string& lease, int64_t now) {
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) return;
  LeaseRec& l = it->second;
  JobRec& j = *s_.jobs.at(l.lease.job);
  TileRec& t = j.tiles[size_t(l.lease.tile)];
  if (t.state != TileState::merging || t.lease != lease) return;
  if (!l.live_at_claim || is_final(j.status.state)) {
    s_.return_to_pending(j, l.lease.tile);
    return;
  }
  // The merge failed on the coordinator's side and the worker retries the upload: the tile stays its, under the
  // lease it held (live again for a lease length), instead of going to the next worker that asks.
  t.state = TileState::leased;
  l.state = LeaseState::live;
  l.lease.deadline_ms = now + s_.config.lease_ms;
  s_.go_live(l);
  watch(l);
  s_.changes.touch_lease(lease);
  s_.touch(j, l.lease.tile);
}

FailResult LeaseFlow::fail(const std::string& lease, const std::string& error, const std::vector<std::string>& log,
                           int64_t now) {
  FailResult r;
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) return r;
  r.status = FailResult::recorded;
  LeaseRec& l = it->second;
  JobRec& j = *s_.jobs.at(l.lease.job);
  const TileRec& t = j.tiles[size_t(l.lease.tile)];
  s_.workers.seen(l.lease.worker, now);
  // Only a lease that was live (or expired before the report arrived) can fail, and only once; a report on an ended
  // job or a finished tile changes nothing.
  if (l.state != LeaseState::live && l.state != LeaseState::expired) return r;
  if (is_final(j.status.state) || t.state == TileState::done || t.state == TileState::merging) {
    if (l.state == LeaseState::live) s_.end_lease(l, LeaseState::failed);
    return r;
  }
  return s_.record_failure(j, l, error, log, now);
}

bool LeaseFlow::release(const std::string& lease) {
  const auto it = s_.leases.find(lease);
  if (it == s_.leases.end()) return false;
  LeaseRec& l = it->second;
  if (l.state != LeaseState::live) return true;
  s_.end_lease(l, LeaseState::released);
  JobRec& j = *s_.jobs.at(l.lease.job);
  const TileRec& t = j.tiles[size_t(l.lease.tile)];
  if (t.state == TileState::leased && t.lease == lease) s_.return_to_pending(j, l.lease.tile);
  return true;
}

int64_t LeaseFlow::expiry_check_ms(const LeaseRec& l) const {
  return std::min(l.lease.deadline_ms,
                  l.granted_ms + s_.jobs.at(l.lease.job)->status.params.tile_timeout_seconds * 1000) + 1;
}

void LeaseFlow::expire(int64_t now) {
  if (now < next_expiry_check_ms_) return;  // nothing can have expired: every operation would otherwise scan them all
  next_expiry_check_ms_ = std::numeric_limits<int64_t>::max();
  std::vector<std::string> timed_out;  // handled after the loop: failing a job ends other live leases
  for (auto it = s_.live_leases.begin(); it != s_.live_leases.end();) {
    LeaseRec& l = s_.leases.at(*it);
    ++it;  // end_lease erases l's entry
    if (now <= l.lease.deadline_ms) {
      if (now - l.granted_ms > s_.jobs.at(l.lease.job)->status.params.tile_timeout_seconds * 1000)
        timed_out.push_back(l.lease.id);
      else
        watch(l);
      continue;
    }
    s_.end_lease(l, LeaseState::expired);
    ++s_.lease_expiries;
    spdlog::info("job {} tile {} worker {}: lease {} expired", l.lease.job, l.lease.tile, l.lease.worker, l.lease.id);
    JobRec& j = *s_.jobs.at(l.lease.job);
    const TileRec& t = j.tiles[size_t(l.lease.tile)];
    if (t.state == TileState::leased && t.lease == l.lease.id) s_.return_to_pending(j, l.lease.tile);
  }
  for (const std::string& id : timed_out) {
    LeaseRec& l = s_.leases.at(id);
    if (l.state != LeaseState::live) continue;  // revoked when an earlier timeout failed its job
    JobRec& j = *s_.jobs.at(l.lease.job);
    const std::string error = "tile timed out after " + std::to_string(j.status.params.tile_timeout_seconds) + " s";
    spdlog::warn("job {} tile {} worker {}: lease {} revoked: {}", l.lease.job, l.lease.tile, l.lease.worker, l.lease.id,
                 error);
    const FailResult f = s_.record_failure(j, l, error, {}, now);
    if (f.job_failed) spdlog::warn("job {}: failed: {}", j.status.id, j.status.error.value_or(""));
  }
}

void LeaseFlow::forget_workers(int64_t now) {
  const int64_t retention = s_.config.worker_retention_ms;
  if (retention <= 0 || now < next_forget_check_ms_) return;
  next_forget_check_ms_ = std::numeric_limits<int64_t>::max();
  // A worker holding a live lease is kept at least until that lease's deadline (it then expires, unless renewed).
  std::map<std::string, int64_t> held;  // worker -> the latest deadline of its live leases
  for (const std::string& id : s_.live_leases) {
    const Lease& l = s_.leases.at(id).lease;
    int64_t& until = held[l.worker];
    until = std::max(until, l.deadline_ms);
  }
  std::vector<std::string> gone;
  for (const auto& [id, w] : s_.workers.all()) {
    // Not before it is offline, its retention has passed and its leases have run out.
    int64_t due = w.last_seen_ms + std::max(retention, s_.workers.gone_ms());
    if (const auto h = held.find(id); h != held.end()) due = std::max(due, h->second);
    if (now > due) gone.push_back(id);
    else next_forget_check_ms_ = std::min(next_forget_check_ms_, due + 1);
  }
  if (gone.empty()) return;
  std::string named;
  for (size_t i = 0; i < gone.size() && i < 3; ++i)
    named += (i ? ", " : "") + gone[i] + " ('" + s_.workers.name_of(gone[i]) + "')";
  spdlog::info("forgot {} worker(s) not seen for {} s or more: {}{}", gone.size(), retention / 1000, named,
               gone.size() > 3 ? ", ..." : "");
  for (const std::string& id : gone) {
    s_.workers.forget(id);
    s_.changes.forget_worker(id);
  }
}

}  // namespace tessera::server
