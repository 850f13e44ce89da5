// How the monitor shows an output layer (core/render/layers.h) as a picture: each layer's channels mapped to RGB.
#pragma once

#include "core/image/image.h"
#include "core/render/layers.h"

namespace tessera::server {

/// An RGB image of `layer` from img's channels of it (img must have them), for the preview PNG: albedo as it is;
/// normals and positions as 0.5 + 0.5 v (positions first divided by their largest finite magnitude); depth as
/// 1 - Z / (largest finite Z), black where infinite; ids as a colour per id (0 black); variance as the square root of
/// each channel over the largest one; Cryptomatte as the colour of each pixel's rank-0 id times its coverage.
/// Throws std::invalid_argument when img lacks a channel of the layer.
Image layer_display(const Image& img, Layer layer);

}  // namespace tessera::server
