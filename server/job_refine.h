// Raising a job's spp (PATCH /v1/jobs/{id} {"spp": M}): when it can be exact, and why not otherwise. A resumable job
// raised to M goes back to running; every tile is leased again and its worker continues from the tile's stored exact
// sums, so the merged result is bitwise the one of a job submitted at M (docs/resume.md says why). job_refine.cpp also
// defines JobService's operations on resumable jobs (raise_spp, with_state, lease_state, resumable_sampling).
#pragma once

#include "protocol/job.h"
#include "protocol/messages.h"

#include <cstdint>
#include <optional>
#include <string>

namespace tessera::server {

/// The sentence a 409 answers when job `status` (submitted as `spec`) cannot be raised to `spp` samples per pixel
/// bitwise as if submitted at it, or nothing when it can: it must have ended well or not at all (not failed or
/// cancelled), have a fixed spp (not adaptive) below `spp`, and have been submitted as resumable.
std::optional<std::string> refine_refusal(const protocol::JobStatus& status, const protocol::JobSpec& spec,
                                          uint32_t spp);

}  // namespace tessera::server
