#include "server/collector.h"

#include <spdlog/spdlog.h>

#include <set>

namespace tessera::server {

Collector::Collector(JobService& jobs, Scheduler& scheduler, BlobStore& blobs, ClockMs clock, RetentionOptions options)
    : jobs_(jobs), sched_(scheduler), blobs_(blobs), clock_(std::move(clock)), opt_(options) {}

protocol::JobState Collector::purge(const std::string& job) {
  const protocol::JobState was = jobs_.purge(job);
  collect_blobs();
  return was;
}

SweepReport Collector::sweep() {
  SweepReport r;
  if (opt_.retain_finished_ms) {
    const int64_t cutoff = clock_() - *opt_.retain_finished_ms;
    for (const JobStatus& s : sched_.jobs()) {
      if (!is_final(s.state) || !s.finished_ms || *s.finished_ms > cutoff) continue;
      try {
        jobs_.purge(s.id);
        r.purged_jobs.push_back(s.id);
      } catch (const protocol::ApiError& e) {
        spdlog::debug("job {}: not purged by the sweep: {}", s.id, e.what());  // retried or being stored: next sweep
      }
    }
    if (!r.purged_jobs.empty())
      spdlog::info("retention: purged {} job(s) that ended more than {} h ago", r.purged_jobs.size(),
                   double(*opt_.retain_finished_ms) / 3'600'000.0);
  }
  r.blobs_removed = collect_blobs();
  return r;
}

size_t Collector::collect_blobs() {
  std::lock_guard lock(mu_);
  const auto held = jobs_.hold_submissions();
  const int64_t cutoff = clock_() - opt_.blob_grace_ms;
  const std::set<std::string> used = jobs_.referenced_blobs();
  size_t removed = 0;
  for (const auto& [sha, touched_ms] : blobs_.list()) {
    if (used.count(sha) || touched_ms > cutoff) continue;
    blobs_.remove(sha);
    ++removed;
  }
  if (removed) spdlog::info("blobs: deleted {} blob(s) no job references", removed);
  return removed;
}

}  // namespace tessera::server
