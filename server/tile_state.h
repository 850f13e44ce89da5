// The tiles of resumable jobs (docs/resume.md): each tile is uploaded with its pixels' exact sums (the UINT channels of
// core/render/render_state.h), stored as uploaded, continued from by the worker that renders it at a higher spp, and
// gathered into the result's state channels so the merged EXR can be refined by `tessera render --resume` too.
#pragma once

#include "core/image/image.h"
#include "core/image/tiles.h"
#include "server/storage.h"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace tessera::server {

/// Why `tile` (an uploaded tile's pixels with their UINT channels) is not a complete state of `spp` samples per pixel
/// with `replicates` replicates, or nothing when it is: the sample channel and every accumulator channel are there,
/// each pixel has spp samples, and its colour is exactly the float mean of its sums.
std::optional<std::string> check_tile_state(const Image& tile, uint32_t spp, uint32_t replicates);

/// The state channels of the whole image (write_state_channels's names), gathered from the stored state of every tile
/// of `grid`; throws std::runtime_error naming a tile whose state is missing, unreadable or of another spp.
std::map<std::string, std::vector<uint32_t>> result_state_channels(JobStore& store, const std::string& job,
                                                                   const TileGrid& grid, uint32_t spp,
                                                                   uint32_t replicates);

}  // namespace tessera::server
