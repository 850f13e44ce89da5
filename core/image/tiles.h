// Cutting an image into square tiles: the unit of work the farm schedules and merges.
#pragma once

#include "core/image/image.h"

#include <cstdint>
#include <stdexcept>

namespace tessera {

/// A width x height image cut into tile_size x tile_size tiles, row-major from the top-left; the last column and row
/// of tiles may be narrower. Tile i covers columns [x0, x1) and rows [y0, y1) with row 0 at the top.
struct TileGrid {
  int width = 0;      ///< Image columns.
  int height = 0;     ///< Image rows.
  int tile_size = 64; ///< Tile edge in pixels.

  /// A grid over a width x height image; throws std::invalid_argument for non-positive sizes.
  TileGrid(int w, int h, int ts) : width(w), height(h), tile_size(ts) {
    if (w <= 0 || h <= 0 || ts <= 0) throw std::invalid_argument("tile grid needs positive width, height and tile size");
  }
  /// Tiles per row.
  int columns() const { return (width + tile_size - 1) / tile_size; }
  /// Tiles per column.
  int rows() const { return (height + tile_size - 1) / tile_size; }
  /// Number of tiles.
  int64_t count() const { return int64_t(columns()) * rows(); }
  /// The pixel window of tile i (0 <= i < count()).
  PixelWindow window(int64_t i) const {
    const int cx = int(i % columns()), cy = int(i / columns());
    const int x0 = cx * tile_size, y0 = cy * tile_size;
    return {x0, y0, std::min(x0 + tile_size, width), std::min(y0 + tile_size, height)};
  }
};

}  // namespace tessera
