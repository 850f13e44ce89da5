// A job as the protocol describes it: its life-cycle state, what it renders and its progress (GET /v1/jobs/{id}).
#pragma once

#include "core/util/enum_names.h"
#include "protocol/defaults.h"
#include "protocol/pipeline.h"
#include "protocol/sequence.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// Life cycle of a job (docs/protocol.md, "Jobs, tiles and leases").
/// waiting: a dependency is not done yet; blocked: a dependency failed, was cancelled or is blocked itself.
enum class JobState { queued, running, paused, done, failed, cancelled, waiting, blocked };
/// Every job state, in declaration order.
inline constexpr JobState kAllJobStates[] = {JobState::queued, JobState::running,   JobState::paused,
                                             JobState::done,   JobState::failed,    JobState::cancelled,
                                             JobState::waiting, JobState::blocked};

/// The protocol's lowercase name of each job state, in declaration order.
inline constexpr std::string_view kJobStateNames[] = {"queued", "running",   "paused",  "done",
                                                      "failed", "cancelled", "waiting", "blocked"};

/// The protocol's lowercase name of a job state.
inline const char* to_string(JobState s) { return enum_c_name(s, kJobStateNames); }
/// Parses a job state name; throws std::invalid_argument for unknown names.
inline JobState job_state_from_string(std::string_view s) {
  return enum_from_name_or_throw<JobState>(s, kJobStateNames, "job state");
}
/// True for states a job never leaves (done, failed, cancelled).
inline bool is_final(JobState s) { return s == JobState::done || s == JobState::failed || s == JobState::cancelled; }
/// True for states a job is held in by its dependencies (waiting, blocked): it gets no lease.
inline bool is_held(JobState s) { return s == JobState::waiting || s == JobState::blocked; }

/// What a job renders and how it is scheduled, fixed at submission.
struct JobParams {
  std::string name;                     ///< Optional label.
  int priority = kDefaultPriority;      ///< Higher is scheduled first.
  int width = 0;                        ///< Image columns.
  int height = 0;                       ///< Image rows.
  int tile_size = kDefaultTileSize;     ///< Tile edge in pixels.
  uint32_t spp = 1;                     ///< Samples per pixel.
  uint64_t seed = 0;                    ///< Sample seed.
  std::string scene_hash;               ///< The loader's content hash of scene and assets.
  int64_t tile_timeout_seconds = kDefaultTileTimeoutSeconds;  ///< A lease older than this (since grant) is revoked.
  FrameOrder frame_order = FrameOrder::in_order;  ///< A sequence: the order its frames are leased in.
  std::string owner;                    ///< The user who submitted it ("" for jobs from before users were recorded).
  std::vector<std::string> require;     ///< Tags a worker must have to be leased its tiles (sorted).
  int64_t max_workers = 0;              ///< Its tiles leased at once at most (a sequence: over all frames); 0: no cap.
  Pipeline pipeline;                    ///< Its dependencies, steps and webhook (protocol/pipeline.h).
};

/// Tile counts of a job.
struct TileCounts {
  int64_t total = 0;    ///< Tiles in the job.
  int64_t done = 0;     ///< Merged tiles.
  int64_t leased = 0;   ///< Tiles under a live lease or being merged.
  int64_t pending = 0;  ///< Tiles waiting for a worker.
};

/// A snapshot of one job.
struct JobStatus {
  std::string id;                       ///< Job id.
  JobParams params;                     ///< What it renders.
  JobState state = JobState::queued;    ///< Where it is in its life cycle.
  TileCounts tiles;                     ///< Tile counts.
  int64_t created_ms = 0;               ///< Submission time.
  std::optional<int64_t> started_ms;    ///< First lease.
  std::optional<int64_t> finished_ms;   ///< Entered a final state.
  std::optional<std::string> error;     ///< Why it failed.
  uint64_t rays = 0;                    ///< Rays reported by workers.
  std::vector<std::string> workers;     ///< Workers whose tiles were merged, in order of first merge.
  double render_seconds = 0;            ///< From the first lease to the end (or to the snapshot's time).
  /// A sequence: its frames by state. Its tiles, rays and workers are its frames' together; its size is its first
  /// frame's and it has no scene hash (each frame has its own).
  std::optional<FrameCounts> frames;
  std::optional<std::string> sequence;  ///< A frame of a sequence: the sequence's id.
  std::optional<int64_t> frame;         ///< A frame of a sequence: its number.
  /// Why a job with pending tiles gets none leased, when it is for want of a worker that may take them (e.g.
  /// "a worker with tags bigmem"); derived when the snapshot is taken.
  std::optional<std::string> waiting_for;
  std::vector<std::string> dependents;  ///< Jobs waiting for this one (params.pipeline.after names its own).
  std::optional<std::string> reason;    ///< Waiting or blocked: which dependency holds it and why.
  std::vector<StepOutput> outputs;      ///< Done with steps (params.pipeline.then): each step's state and files.
  /// True for done, failed and cancelled.
  bool finished() const { return is_final(state); }
};

/// The job object of GET /v1/jobs/{id} (params flattened into it, tiles as an object).
void to_json(nlohmann::json& j, const JobStatus& s);
/// Reads a job object; id and state are required, the rest defaults; throws ProtocolError naming the field.
void from_json(const nlohmann::json& j, JobStatus& s);

}  // namespace tessera::protocol
