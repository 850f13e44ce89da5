#include "core/image/contact_sheet.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace tessera {

Image thumbnail(const Image& img, int width) {
  if (img.width < 1 || img.height < 1) throw ImageError("thumbnail of an empty image");
  if (width < 1) throw ImageError("thumbnail width must be at least 1 (got " + std::to_string(width) + ")");
  const int height = std::max(1, int(std::lround(double(img.height) * width / img.width)));
  Image out;
  out.width = width;
  out.height = height;
  out.rgb.assign(size_t(width) * size_t(height) * 3, 0.f);
  // Source columns [x0, x1) and rows [y0, y1) of each output pixel: the integer blocks that tile the source.
  const auto span = [](int i, int n, int src) {
    int a = int(int64_t(i) * src / n), b = int(int64_t(i + 1) * src / n);
    return std::pair{a, std::max(b, a + 1)};
  };
  for (int y = 0; y < height; ++y) {
    const auto [y0, y1] = span(y, height, img.height);
    for (int x = 0; x < width; ++x) {
      const auto [x0, x1] = span(x, width, img.width);
      double sum[3] = {0, 0, 0};
      for (int sy = y0; sy < y1; ++sy)
        for (int sx = x0; sx < x1; ++sx) {
          const size_t i = (size_t(sy) * size_t(img.width) + size_t(sx)) * 3;
          for (int c = 0; c < 3; ++c) sum[c] += img.rgb[i + size_t(c)];
        }
      const double n = double(y1 - y0) * double(x1 - x0);
      const size_t o = (size_t(y) * size_t(width) + size_t(x)) * 3;
      for (int c = 0; c < 3; ++c) out.rgb[o + size_t(c)] = float(sum[c] / n);
    }
  }
  return out;
}

Image contact_sheet(const std::vector<Image>& images, int columns, int gap) {
  if (images.empty()) throw ImageError("a contact sheet needs at least one image");
  if (gap < 0) throw ImageError("a contact sheet's gap cannot be negative");
  const int n = int(images.size());
  if (columns <= 0) columns = int(std::ceil(std::sqrt(double(n))));
  columns = std::min(columns, n);
  const int rows = (n + columns - 1) / columns;
  int cell_w = 0;
  for (const Image& i : images) cell_w = std::max(cell_w, i.width);
  std::vector<int> row_h(size_t(rows), 0);
  for (int k = 0; k < n; ++k) row_h[size_t(k / columns)] = std::max(row_h[size_t(k / columns)], images[size_t(k)].height);
  Image out;
  out.width = gap + columns * (cell_w + gap);
  out.height = gap;
  for (int h : row_h) out.height += h + gap;
  out.rgb.assign(size_t(out.width) * size_t(out.height) * 3, 0.f);
  int top = gap;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns && r * columns + c < n; ++c) {
      const Image& img = images[size_t(r * columns + c)];
      const int left = gap + c * (cell_w + gap);
      for (int y = 0; y < img.height; ++y)
        std::copy_n(img.rgb.begin() + ptrdiff_t(size_t(y) * size_t(img.width) * 3), size_t(img.width) * 3,
                    out.rgb.begin() + ptrdiff_t((size_t(top + y) * size_t(out.width) + size_t(left)) * 3));
    }
    top += row_h[size_t(r)] + gap;
  }
  return out;
}

}  // namespace tessera
