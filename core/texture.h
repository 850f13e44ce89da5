// Textures of the course format: a constant colour, or an EXR image looked up through uvmapping2d.
#pragma once

#include "core/image.h"
#include "core/math.h"

#include <memory>

namespace tessera {

/// A texture: constant when `image` is null, otherwise an image with bilinear filtering and repeat wrapping.
struct Texture {
  Vec3 color{1.f};                     ///< Constant colour (image == nullptr).
  std::shared_ptr<const Image> image;  ///< Linear RGB image, row 0 = top (v = 0).
  Vec2 scale{1.f};                     ///< uvmapping2d scale.
  Vec2 delta{0.f};                     ///< uvmapping2d delta: lookup st = scale * uv + delta.

  /// Value at texture coordinate uv.
  Vec3 evaluate(Vec2 uv) const { return image ? lookup(scale * uv + delta) : color; }

  /// Bilinear lookup at st (repeat wrap); pixel centres sit at (i + 0.5)/w, (j + 0.5)/h, v = 0 is the top row.
  Vec3 lookup(Vec2 st) const { return lookup(st, false); }

  /// Bilinear lookup for an equirectangular map: repeat in s (longitude), clamp in t, so that texels near one
  /// pole never blend with the other pole's row.
  Vec3 lookup_latlong(Vec2 st) const { return lookup(st, true); }

 private:
  Vec3 lookup(Vec2 st, bool clamp_t) const;
};

}  // namespace tessera
