// One job's tiles as the protocol describes them: where a tile is, and the answer of GET /v1/jobs/{id}/tiles
// (docs/protocol.md, "Tiles").
#pragma once

#include "core/image/pixel_window.h"
#include "core/util/enum_names.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// Where a tile is: pending (waiting), leased (a worker renders it), merging (an upload is being stored), done.
enum class TileState { pending, leased, merging, done };
/// The lowercase name of each tile state (as stored and answered), in declaration order.
inline constexpr std::string_view kTileStateNames[] = {"pending", "leased", "merging", "done"};

/// The lowercase name of a tile state (as stored and answered).
inline const char* to_string(TileState s) { return enum_c_name(s, kTileStateNames); }
/// Parses a tile state name; throws std::invalid_argument for unknown names.
inline TileState tile_state_from_string(std::string_view s) {
  return enum_from_name_or_throw<TileState>(s, kTileStateNames, "tile state");
}

/// The most log lines a failure report carries, and the longest line (bytes); longer reports are refused (400).
inline constexpr size_t kMaxFailureLogLines = 50;
inline constexpr size_t kMaxFailureLogLineBytes = 1000;
/// The longest failure text stored (bytes); a longer one is cut and marked (protocol::bounded_text).
inline constexpr size_t kMaxFailureErrorBytes = 4096;

/// A worker's latest failure on a tile.
struct TileFailure {
  std::string worker;             ///< Worker id.
  std::string worker_name;        ///< Its self-reported name ("" when unknown).
  std::string error;              ///< What it reported (or "tile timed out after N s").
  std::vector<std::string> log;   ///< The log lines it sent with the report, oldest first.
};

/// One tile of a job.
struct TileInfo {
  int64_t index = 0;                         ///< Tile number.
  PixelWindow window;                        ///< Its pixels, half-open, row 0 at the top.
  std::string state = "pending";             ///< pending, leased, merging (an upload is being stored or flushed) or done.
  std::optional<std::string> worker;         ///< Worker holding its live lease (leased, merging).
  std::optional<std::string> worker_name;    ///< That worker's name.
  int64_t attempts = 0;                      ///< Leases granted for it.
  std::optional<double> render_seconds;      ///< Lease grant to upload of the accepted result (done tiles).
  uint64_t rays = 0;                         ///< Rays the accepted result's worker reported (done tiles).
  std::optional<std::string> rendered_by;    ///< The worker whose result was accepted (done tiles).
  std::optional<std::string> rendered_by_name;  ///< That worker's name ("" once the coordinator forgot it).
  std::vector<TileFailure> failures;         ///< Each failing worker's latest failure, by worker id.
  std::vector<std::string> log;              ///< Done tiles: the log lines sent with the accepted upload, oldest first.
  bool log_not_kept = false;                 ///< Done tiles: a log came, but the job's tile logs were full.
};

/// Answer of GET /v1/jobs/{id}/tiles.
struct TileList {
  std::string job;               ///< Job id.
  std::vector<TileInfo> tiles;   ///< Every tile in index order.
  int64_t logs_not_kept = 0;     ///< Done tiles whose log was not kept (the job's tile logs were full).
};

void to_json(nlohmann::json& j, const TileFailure& f);
void from_json(const nlohmann::json& j, TileFailure& f);
void to_json(nlohmann::json& j, const TileInfo& t);
/// Reads a tile object; index and state are required; throws ProtocolError naming the field.
void from_json(const nlohmann::json& j, TileInfo& t);
void to_json(nlohmann::json& j, const TileList& l);
void from_json(const nlohmann::json& j, TileList& l);

}  // namespace tessera::protocol
