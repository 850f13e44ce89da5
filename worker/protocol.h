// The farm protocol's messages (docs/protocol.md) as structs, parsed from and written to JSON.
#pragma once

#include "core/image.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

namespace tessera::farm {

/// A coordinator answer that does not follow the protocol (missing or mistyped fields, not JSON).
struct ProtocolError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Parses a response body as JSON; throws ProtocolError naming `what` on malformed text.
nlohmann::json parse_body(const std::string& body, const std::string& what);

/// Answer to POST /v1/workers.
struct Registration {
  std::string id;              ///< Worker id (w-…).
  double lease_seconds = 30;   ///< Lease length.
  double heartbeat_seconds = 5;  ///< Heartbeat period.
};
/// Parses a registration; throws ProtocolError.
Registration parse_registration(const nlohmann::json& j);

/// Answer 200 to POST /v1/workers/{wid}/lease.
struct Lease {
  std::string id;          ///< Lease id (l-…).
  std::string job;         ///< Job id.
  int64_t tile = 0;        ///< Tile number.
  PixelWindow window;      ///< Tile pixels, half-open, row 0 at the top.
  uint32_t spp = 1;        ///< Samples per pixel.
  uint64_t seed = 0;       ///< Sample seed.
  std::string scene_hash;  ///< Scene hash (informative).
};
/// Parses a lease; throws ProtocolError.
Lease parse_lease(const nlohmann::json& j);

/// Answer to GET /v1/jobs/{id}/spec.
struct JobSpec {
  nlohmann::json scene;                       ///< The scene file's JSON.
  std::map<std::string, std::string> assets;  ///< Asset path as written in the scene -> SHA-256.
  uint32_t spp = 1;                           ///< Samples per pixel.
  uint64_t seed = 0;                          ///< Seed.
  int width = 0;                              ///< Image width.
  int height = 0;                             ///< Image height.
  std::string integrator;                     ///< "direct" when the job was submitted with it, else empty.
  double target_error = 0.0;                  ///< Adaptive sampling target (0: every pixel gets spp samples).
  uint32_t min_spp = 16;                      ///< Adaptive sampling: first round.
  uint32_t max_spp = 1024;                    ///< Adaptive sampling: most samples per pixel.
};
/// Parses a job spec; throws ProtocolError.
JobSpec parse_job_spec(const nlohmann::json& j);

/// A job as GET /v1/jobs/{id} describes it (the fields clients use).
struct JobStatus {
  std::string id;     ///< Job id.
  std::string state;  ///< queued, running, done, failed or cancelled.
  int width = 0;      ///< Image width.
  int height = 0;     ///< Image height.
  int64_t tiles_total = 0;   ///< Tiles in the job.
  int64_t tiles_done = 0;    ///< Tiles merged.
  int64_t tiles_leased = 0;  ///< Tiles being rendered.
  double render_seconds = 0; ///< Wall time from the first lease to the end (or to now).
  uint64_t rays = 0;         ///< Rays reported by workers so far.
  std::string error;  ///< Failure reason (failed jobs).
  /// True for done, failed and cancelled.
  bool finished() const { return state == "done" || state == "failed" || state == "cancelled"; }
};
/// Parses a job; throws ProtocolError.
JobStatus parse_job_status(const nlohmann::json& j);

}  // namespace tessera::farm
