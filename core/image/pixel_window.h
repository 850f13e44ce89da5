// A rectangle of pixels: the window a render, a crop, a tile or an EXR's data covers.
#pragma once

namespace tessera {

/// A half-open pixel rectangle [x0,x1) x [y0,y1); y = 0 is the top row of the picture.
struct PixelWindow {
  int x0 = 0;  ///< First column.
  int y0 = 0;  ///< First row.
  int x1 = 0;  ///< One past the last column.
  int y1 = 0;  ///< One past the last row.

  /// Number of columns (zero for an empty window).
  int width() const { return empty() ? 0 : x1 - x0; }
  /// Number of rows (zero for an empty window).
  int height() const { return empty() ? 0 : y1 - y0; }
  /// True when the window holds no pixel.
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  /// True when every pixel of w lies inside this window (always true for an empty w).
  bool contains(const PixelWindow& w) const {
    return w.empty() || (w.x0 >= x0 && w.y0 >= y0 && w.x1 <= x1 && w.y1 <= y1);
  }
  /// Exact equality of the four bounds.
  bool operator==(const PixelWindow&) const = default;
};

}  // namespace tessera
