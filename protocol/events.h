// The events of GET /v1/events (Server-Sent Events, docs/protocol.md "Events"): their names and payloads.
#pragma once

#include "protocol/job.h"
#include "protocol/worker.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace tessera::protocol {

/// Event names (the SSE `event:` field).
namespace events {
inline constexpr const char* kJob = "job";                  ///< A job changed state (or priority); data: JobStatus.
inline constexpr const char* kTileLeased = "tile_leased";   ///< data: TileEvent (with lease).
inline constexpr const char* kTileDone = "tile_done";       ///< data: TileEvent.
inline constexpr const char* kTileFailed = "tile_failed";   ///< data: TileEvent (with error).
inline constexpr const char* kWorkerSeen = "worker_seen";   ///< data: WorkerEvent (reason registered or back).
inline constexpr const char* kWorkerLost = "worker_lost";   ///< data: WorkerEvent (reason offline).
inline constexpr const char* kTileRequeued = "tile_requeued";    ///< An operator requeued a tile; data: TileEvent.
inline constexpr const char* kJobRemoved = "job_removed";        ///< A job was purged; data: PurgeAnswer.
inline constexpr const char* kWorkerChanged = "worker_changed";  ///< data: WorkerEvent (reason draining or undrained).
inline constexpr const char* kFrameDone = "frame_done";          ///< A sequence's frame was written; data: FrameEvent.
inline constexpr const char* kResync = "resync";            ///< Events were missed: reload the state; data: {}.
/// Every event a stream can be limited to (`GET /v1/events?only=...`); resync is always sent.
inline constexpr const char* kFilterable[] = {kJob, kTileLeased, kTileDone, kTileFailed, kWorkerSeen,
                                              kWorkerLost, kTileRequeued, kJobRemoved, kWorkerChanged, kFrameDone};
}  // namespace events

/// What happened to one tile.
struct TileEvent {
  std::string job;                    ///< Job id.
  int64_t tile = 0;                   ///< Tile index.
  std::string worker;                 ///< The worker that leased, rendered or failed it ("" for tile_requeued).
  std::optional<std::string> lease;   ///< The lease (tile_leased).
  std::optional<std::string> error;   ///< The worker's error text (tile_failed).
};
void to_json(nlohmann::json& j, const TileEvent& e);
void from_json(const nlohmann::json& j, TileEvent& e);

/// A frame of a sequence whose result was written.
struct FrameEvent {
  std::string job;        ///< The sequence's id.
  int64_t frame = 0;      ///< The frame's number.
  std::string frame_job;  ///< The frame's own job id.
};
void to_json(nlohmann::json& j, const FrameEvent& e);
void from_json(const nlohmann::json& j, FrameEvent& e);

/// A worker that came or went.
struct WorkerEvent {
  std::string reason;   ///< "registered", "back" (seen again after being offline), "offline", "draining", "undrained".
  WorkerInfo worker;    ///< The worker as it is now.
};
void to_json(nlohmann::json& j, const WorkerEvent& e);
void from_json(const nlohmann::json& j, WorkerEvent& e);

}  // namespace tessera::protocol
