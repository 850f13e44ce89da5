// The log lines a worker sends with a tile's upload (PUT /v1/leases/{lease}/result, header kTileLogHeader): what it
// logged about the lease, shown with the done tile (docs/protocol.md, "Tile logs").
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// Header of a tile result upload: the worker's last log lines about the lease, a JSON array of strings written in
/// ASCII (other characters as \u escapes). Optional: an upload without it is a tile without a log.
inline constexpr const char* kTileLogHeader = "X-Tessera-Log";
/// The most lines an upload's log carries, and the longest line (bytes): fewer than a failure report's
/// (protocol/tile.h), since they travel in a header. Longer logs are refused (400).
inline constexpr size_t kMaxTileLogLines = 20;
inline constexpr size_t kMaxTileLogLineBytes = 300;
/// The longest kTileLogHeader value (bytes) the coordinator reads; a longer one is refused (400) unparsed.
inline constexpr size_t kMaxTileLogHeaderBytes = 4096;

/// The header value for `lines` (oldest first): each line cut to kMaxTileLogLineBytes (at a character boundary), only
/// the last kMaxTileLogLines, and the oldest dropped until the value fits kMaxTileLogHeaderBytes. "" for no lines.
std::string tile_log_header(const std::vector<std::string>& lines);
/// The lines of a header value ("": none); throws ProtocolError (400) for one that is too long, not a JSON array of
/// strings, or beyond the bounds above.
std::vector<std::string> parse_tile_log_header(std::string_view value);

}  // namespace tessera::protocol
