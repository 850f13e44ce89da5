// Textures of the course format: a constant colour, an EXR image looked up through uvmapping2d, or a checkerboard.
#pragma once

#include "core/image/image.h"
#include "core/util/math.h"

#include <memory>

namespace tessera {

/// A texture: an image with bilinear filtering and repeat wrapping when `image` is set, else a checkerboard of
/// `color` and `color1` when `checkerboard`, else the constant `color`.
struct Texture {
  Vec3 color{1.f};                     ///< Constant colour, or the checkerboard's color0.
  std::shared_ptr<const Image> image;  ///< Linear RGB image, row 0 = top (v = 0).
  bool checkerboard = false;           ///< A checkerboard of color / color1 (image == nullptr).
  Vec3 color1{0.2f};                   ///< The checkerboard's color1.
  Vec2 scale{1.f};                     ///< uvmapping2d scale.
  Vec2 delta{0.f};                     ///< uvmapping2d delta: lookup st = scale * uv + delta.

  /// Value at texture coordinate uv.
  Vec3 evaluate(Vec2 uv) const {
    if (image) return lookup(scale * uv + delta);
    return checkerboard ? checker(scale * uv + delta) : color;
  }

  /// The checkerboard at st: cells 0.5 wide; a = trunc(2 s) mod 2, b = trunc(2 t) mod 2 (in {0, 1}); color when
  /// a == b, color1 otherwise (docs/scene-format.md).
  Vec3 checker(Vec2 st) const;

  /// Bilinear lookup at st (repeat wrap); pixel centres sit at (i + 0.5)/w, (j + 0.5)/h, v = 0 is the top row.
  Vec3 lookup(Vec2 st) const { return lookup(st, false); }

  /// Bilinear lookup for an equirectangular map: repeat in s (longitude), clamp in t, so that texels near one
  /// pole never blend with the other pole's row.
  Vec3 lookup_latlong(Vec2 st) const { return lookup(st, true); }

 private:
  Vec3 lookup(Vec2 st, bool clamp_t) const;
};

}  // namespace tessera
