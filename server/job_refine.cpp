#include "server/job_refine.h"

namespace tessera::server {

std::optional<std::string> refine_refusal(const protocol::JobStatus& status, const protocol::JobSpec& spec,
                                          uint32_t spp) {
  const std::string job = "job " + status.id;
  if (status.state == protocol::JobState::failed || status.state == protocol::JobState::cancelled)
    return job + " is " + protocol::to_string(status.state) +
           ": retry it first (POST /v1/jobs/" + status.id + "/retry), then raise its spp";
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

}  // namespace tessera::server
