// A contact sheet: small copies of many images (a sequence's frames) laid out in a grid, to look at a shot at once.
#pragma once

#include "core/image/image.h"

#include <vector>

namespace tessera {

/// A copy of `img` `width` columns wide and as many rows as keep its aspect (at least 1), each pixel the mean of the
/// block of source pixels it covers (a box filter: exact block means for whole-number factors); an image narrower
/// than `width` is enlarged by repeating pixels. Throws ImageError for an empty image or a width below 1.
Image thumbnail(const Image& img, int width);

/// The images laid out in order, `columns` to a row (0: the smallest count whose square holds them all), `gap`
/// black pixels between cells and around them; each cell is as wide as the widest image and each row as tall as its
/// tallest, an image sitting at its cell's top left. Throws ImageError for no images or a negative gap.
Image contact_sheet(const std::vector<Image>& images, int columns = 0, int gap = 2);

}  // namespace tessera
