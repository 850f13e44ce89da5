#include "server/job_refine.h"

#include "server/job_service.h"

#include <spdlog/spdlog.h>

#include <mutex>

namespace tessera::server {

using protocol::ApiError;

std::optional<std::string> refine_refusal(const protocol::JobStatus& status, const protocol::JobSpec& spec,
                                          uint32_t spp) {
  const std::string job = "job " + status.id;
  if (status.state == protocol::JobState::failed || status.state == protocol::JobState::cancelled)
    return job + " is " + protocol::to_string(status.state) +
           ": retry it first (POST " + protocol::routes::job_retry(status.id) + "), then raise its spp";
  if (spec.sampling.target_error > 0.0)
    return job + " uses adaptive sampling (target_error): each pixel stopped at its own sample count, so there is no "
                 "common spp to raise";
  if (!spec.resumable)
    return job + " was not submitted as resumable: its tiles keep only float32 colours, not the exact per-pixel sums a "
                 "continuation needs (submit with \"resumable\": true, `tessera submit --resumable`)";
  if (spp <= status.params.spp)
    return job + " has " + std::to_string(status.params.spp) + " spp: it can only be raised (asked for " +
           std::to_string(spp) + ")";
  return std::nullopt;
}

// JobService's operations on resumable jobs (declared in job_service.h, defined here with the rules they follow).

protocol::JobStatus JobService::raise_spp(const std::string& id, uint32_t spp) {
  std::lock_guard one_at_a_time(raise_mu_);
  refuse_frame(id, "raise the spp of");
  const protocol::JobStatus before = status(id);
  if (before.frames)
    throw ApiError(409, "job " + id + " is a sequence: its spp cannot be raised (submit the frames again at the new spp)");
  protocol::JobSpec sp = spec(id);
  if (const auto why = refine_refusal(before, sp, spp)) throw ApiError(409, *why);
  check_samples(before.params.width, before.params.height, spp, false);
  const RaiseResult r = sched_.raise_spp(id, spp);
  switch (r.status) {
    case RaiseResult::unknown: throw ApiError(404, "no job " + id);
    case RaiseResult::wrong_state:
    case RaiseResult::not_higher: throw ApiError(409, *refine_refusal(*sched_.job(id), sp, spp));  // changed meanwhile
    case RaiseResult::merging:
      throw ApiError(409, "job " + id + " is merging an uploaded tile at this moment; try again");
    case RaiseResult::raised: break;
  }
  // The record follows the scheduler, whose spp is the job's (finalize records that one if a crash came between);
  // raise_mu_ keeps concurrent raises from storing their records out of order.
  sp.sampling.spp = spp;
  jobs_.save_record(id, sp);
  {
    std::lock_guard lock(mu_);
    cache_spec_locked(id, sp, true);
  }
  spdlog::info("job {}: spp raised from {} to {} (was {}), {} lease(s) revoked; every tile continues from its stored "
               "state", id, before.params.spp, spp, to_string(r.was), r.revoked_leases);
  return r.job;
}

std::optional<protocol::SamplingSettings> JobService::resumable_sampling(const std::string& job) {
  // From the cached spec without copying it (this runs for every lease and upload).
  const auto cached = [&]() -> std::optional<std::optional<protocol::SamplingSettings>> {
    std::lock_guard lock(mu_);
    const auto it = specs_.find(job);
    if (it == specs_.end()) return std::nullopt;
    if (!it->second.resumable) return std::optional<protocol::SamplingSettings>();
    return std::optional<protocol::SamplingSettings>(it->second.sampling);
  };
  if (auto r = cached()) return *r;
  try {
    spec(job);  // loads the record into the cache
  } catch (const ApiError&) {  // no record: a job of an older version, not resumable
    return std::nullopt;
  }
  return cached().value_or(std::nullopt);
}

LayerSet JobService::job_layers(const std::string& job) {
  const auto cached = [&]() -> std::optional<LayerSet> {
    std::lock_guard lock(mu_);
    const auto it = specs_.find(job);
    if (it == specs_.end()) return std::nullopt;
    return it->second.sampling.layers;
  };
  if (auto r = cached()) return *r;
  try {
    spec(job);  // loads the record into the cache
  } catch (const ApiError&) {  // no record (a job of an older version) or a sequence: no layers
    return LayerSet{};
  }
  return cached().value_or(LayerSet{});
}

protocol::Lease JobService::with_state(protocol::Lease lease) {
  if (!resumable_sampling(lease.job)) return lease;
  lease.resumable = true;
  // Only a state of fewer samples is continued: a tile leased again at its own spp (e.g. its upload was never
  // acknowledged) is rendered afresh rather than copied from what was stored.
  const std::optional<uint32_t> stored = jobs_.tile_state_spp(lease.job, lease.tile);
  if (stored && *stored < lease.spp) lease.state_spp = *stored;
  return lease;
}

std::string JobService::lease_state(const std::string& lease) {
  const ResultClaim c = sched_.check_result(lease);
  if (c.status == ResultClaim::unknown) throw ApiError(404, "unknown lease " + lease);
  auto stored = jobs_.tile_state(c.job, c.tile);
  if (!stored) throw ApiError(404, "tile " + std::to_string(c.tile) + " of job " + c.job + " has no stored state");
  return std::move(stored->second);
}

}  // namespace tessera::server
