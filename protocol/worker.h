// A worker as the coordinator reports it (GET /v1/workers): what it is doing, what it has done, what it may not take.
#pragma once

#include "core/util/enum_names.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// offline: not seen for three lease lengths; draining: takes no new tiles (it may still finish one); rendering: holds
/// a lease; idle: none of those.
enum class WorkerState { idle, rendering, draining, offline };
/// Every worker state, in declaration order.
inline constexpr WorkerState kAllWorkerStates[] = {WorkerState::idle, WorkerState::rendering, WorkerState::draining,
                                                   WorkerState::offline};

/// The protocol's lowercase name of each worker state, in declaration order.
inline constexpr std::string_view kWorkerStateNames[] = {"idle", "rendering", "draining", "offline"};

/// The protocol's lowercase name of a worker state.
inline const char* to_string(WorkerState s) { return enum_c_name(s, kWorkerStateNames); }
/// Parses a worker state name; throws std::invalid_argument for unknown names.
inline WorkerState worker_state_from_string(std::string_view s) {
  return enum_from_name_or_throw<WorkerState>(s, kWorkerStateNames, "worker state");
}

/// One worker of GET /v1/workers.
struct WorkerInfo {
  std::string id;                            ///< Worker id (w-…).
  std::string name;                          ///< Self-reported name.
  WorkerState state = WorkerState::idle;     ///< What it is doing.
  std::optional<std::string> job;           ///< The job of the tile it renders, if any.
  std::optional<int64_t> tile;               ///< The tile it renders, if any.
  int64_t threads = 0;                       ///< Render threads it announced (0: unknown).
  int64_t tiles_done = 0;                    ///< Tiles of it the coordinator accepted.
  uint64_t rays = 0;                         ///< Rays of those tiles.
  double render_seconds = 0;                 ///< Their render times (lease grant to acceptance), summed.
  int64_t last_seen_ms = 0;                  ///< Last request from it (Unix ms).
  std::vector<std::string> blocklisted_for;  ///< Unfinished jobs it failed too often to be given tiles of.
  std::vector<std::string> tags;             ///< What it offers (protocol/tags.h), as it registered.
};
void to_json(nlohmann::json& j, const WorkerInfo& w);
void from_json(const nlohmann::json& j, WorkerInfo& w);

/// Answer of GET /v1/workers.
struct WorkerList {
  std::vector<WorkerInfo> workers;  ///< Every registered worker, by id.
};
void to_json(nlohmann::json& j, const WorkerList& l);
void from_json(const nlohmann::json& j, WorkerList& l);

}  // namespace tessera::protocol
