#include "server/farm_queries.h"

#include "core/image/tiles.h"

#include <algorithm>
#include <map>
#include <string_view>

namespace tessera::server {

std::optional<JobStatus> FarmQueries::job(const std::string& id, int64_t now) const {
  const auto it = s_.jobs.find(id);
  if (it == s_.jobs.end()) return std::nullopt;
  return s_.snapshot(*it->second, now);
}

std::optional<FramePage> FarmQueries::frames(const std::string& id, std::optional<int64_t> after, size_t limit,
                                             int64_t now) const {
  const auto it = s_.jobs.find(id);
  if (it == s_.jobs.end() || !it->second->is_sequence()) return std::nullopt;
  const std::vector<JobRec*>& all = it->second->frames;
  auto from = all.begin();
  if (after)
    from = std::upper_bound(all.begin(), all.end(), *after,
                            [](int64_t v, const JobRec* f) { return v < *f->status.frame; });
  FramePage page;
  for (auto f = from; f != all.end(); ++f) {
    if (limit > 0 && page.frames.size() == limit) {
      page.more = true;
      break;
    }
    page.frames.push_back(s_.snapshot(**f, now));
  }
  return page;
}

JobPage FarmQueries::jobs(const JobQuery& q, int64_t now) const {
  std::vector<const JobRec*> recs;
  for (const auto& [id, j] : s_.jobs)
    if (!j->sequence && (!q.after || j->seq < *q.after) && (q.owner.empty() || j->status.params.owner == q.owner) &&
        (q.states.empty() || q.states.count(s_.state_of(*j))))
      recs.push_back(j.get());
  std::sort(recs.begin(), recs.end(), [](const JobRec* a, const JobRec* b) { return a->seq > b->seq; });
  JobPage page;
  if (q.limit > 0 && recs.size() > q.limit) {
    recs.resize(q.limit);
    page.more = true;
  }
  for (const JobRec* j : recs) {
    page.jobs.push_back(s_.snapshot(*j, now));
    page.seqs.push_back(j->seq);
  }
  return page;
}

std::optional<uint64_t> FarmQueries::job_seq(const std::string& id) const {
  const auto it = s_.jobs.find(id);
  if (it == s_.jobs.end()) return std::nullopt;
  return it->second->seq;
}

std::optional<protocol::TileList> FarmQueries::tiles(const std::string& job) const {
  const auto it = s_.jobs.find(job);
  if (it == s_.jobs.end()) return std::nullopt;
  const JobParams& p = it->second->status.params;
  const TileGrid grid(p.width, p.height, p.tile_size);
  protocol::TileList out{job, {}, it->second->logs_not_kept};
  out.tiles.reserve(it->second->tiles.size());
  for (size_t i = 0; i < it->second->tiles.size(); ++i) {
    const TileRec& t = it->second->tiles[i];
    protocol::TileInfo v;
    v.index = int64_t(i);
    v.window = grid.window(v.index);
    v.state = t.unflushed ? to_string(TileState::merging) : to_string(t.state);
    v.attempts = t.attempts;
    if (t.render_ms >= 0) v.render_seconds = double(t.render_ms) / 1000.0;
    v.rays = t.rays;
    const auto l = t.state == TileState::pending || t.state == TileState::done ? s_.leases.end() : s_.leases.find(t.lease);
    if (l != s_.leases.end()) {
      v.worker = l->second.lease.worker;
      v.worker_name = s_.workers.name_of(*v.worker);
    }
    if (t.state == TileState::done && !t.rendered_by.empty()) {
      v.rendered_by = t.rendered_by;
      v.rendered_by_name = s_.workers.name_of(t.rendered_by);
    }
    for (const auto& [worker, error] : t.failures) {
      const auto log = t.logs.find(worker);
      v.failures.push_back(
          {worker, s_.workers.name_of(worker), error, log == t.logs.end() ? std::vector<std::string>{} : log->second});
    }
    if (t.state == TileState::done) {
      v.log = t.log;
      v.log_not_kept = t.log_not_kept;
    }
    out.tiles.push_back(std::move(v));
  }
  return out;
}

std::vector<protocol::WorkerInfo> FarmQueries::workers(int64_t now) const {
  // Each worker's lease and blocklists, gathered in one pass over the live leases and the jobs (not one per worker).
  std::map<std::string_view, const Lease*> holding;
  for (const std::string& lid : s_.live_leases) {
    const Lease& l = s_.leases.at(lid).lease;
    holding.emplace(l.worker, &l);  // the first in id order, as worker() picks it
  }
  std::map<std::string_view, std::vector<std::string>> blocklists;
  for (const auto& [jid, j] : s_.jobs) {
    if (is_final(j->status.state)) continue;
    for (const auto& [worker, failures] : j->worker_failures)
      if (failures >= s_.config.worker_failure_limit) blocklists[worker].push_back(jid);
  }
  std::vector<protocol::WorkerInfo> out;
  out.reserve(s_.workers.size());
  for (const auto& [id, w] : s_.workers.all()) {
    const auto h = holding.find(id);
    const auto b = blocklists.find(id);
    out.push_back(s_.workers.info(id, w, now, h == holding.end() ? nullptr : h->second,
                                  b == blocklists.end() ? std::vector<std::string>{} : std::move(b->second)));
  }
  return out;
}

std::optional<protocol::WorkerInfo> FarmQueries::worker(const std::string& id, int64_t now) const {
  const WorkerRec* w = s_.workers.find(id);
  if (!w) return std::nullopt;
  const Lease* holding = nullptr;
  for (const std::string& lid : s_.live_leases) {
    const Lease& l = s_.leases.at(lid).lease;
    if (l.worker != id) continue;
    holding = &l;
    break;
  }
  std::vector<std::string> blocklisted_for;
  for (const auto& [jid, j] : s_.jobs)
    if (!is_final(j->status.state) && s_.blocklisted(*j, id)) blocklisted_for.push_back(jid);
  return s_.workers.info(id, *w, now, holding, std::move(blocklisted_for));
}

SchedulerCounters FarmQueries::counters() const {
  SchedulerCounters c;
  for (JobState st : protocol::kAllJobStates) c.jobs[st] = 0;
  for (const auto& [id, j] : s_.jobs)
    if (!j->sequence) ++c.jobs[s_.state_of(*j)];  // a sequence counts as one job
  c.tiles_rendered = s_.tiles_rendered;
  c.lease_expiries = s_.lease_expiries;
  c.rays = s_.rays;
  c.workers = int64_t(s_.workers.size());
  c.active_leases = int64_t(s_.live_leases.size());
  return c;
}

std::vector<std::string> FarmQueries::unfinalized_jobs() const {
  std::vector<std::string> out;
  for (const auto& [key, j] : s_.queue)
    if (started_and_open(j->status) && j->status.tiles.done == j->status.tiles.total) out.push_back(j->status.id);
  return out;
}

}  // namespace tessera::server
