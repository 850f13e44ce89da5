#include "core/render/texture.h"

#include <cmath>

namespace tessera {

namespace {

// trunc(2 x) mod 2 in {0, 1}, for any finite x (in double: no integer overflow for large x).
int checker_parity(float x) { return std::fmod(std::trunc(2.0 * double(x)), 2.0) != 0.0 ? 1 : 0; }

}  // namespace

Vec3 Texture::checker(Vec2 st) const {
  if (!std::isfinite(st.x) || !std::isfinite(st.y)) return color;
  return checker_parity(st.x) == checker_parity(st.y) ? color : color1;
}

Vec3 Texture::lookup(Vec2 st, bool clamp_t) const {
  const int w = image->width, h = image->height;
  if (w <= 0 || h <= 0) return Vec3(0.f);
  if (!std::isfinite(st.x) || !std::isfinite(st.y)) return image->at(0, 0);
  const float x = st.x * float(w) - 0.5f, y = st.y * float(h) - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  // v mod n in [0, n) for the integer-valued v = floor(...): inside the image as it is, else by integer remainder
  // (what the exact double fmod gives for |v| < 2^31), and by fmod beyond.
  auto wrap = [](float v, int n) {
    if (v >= 0.f && v < float(n)) return int(v);
    if (std::abs(v) < 2147483648.f) {
      const int i = int(v) % n;
      return i < 0 ? i + n : i;
    }
    const double m = std::fmod(double(v), double(n));
    int i = int(m < 0 ? m + n : m);
    return i >= n ? 0 : i;
  };
  auto clamp = [](float v, int n) { return v < 0.f ? 0 : (v >= float(n - 1) ? n - 1 : int(v)); };
  const int x0 = wrap(fx, w), x1 = wrap(fx + 1.f, w);
  const int y0 = clamp_t ? clamp(fy, h) : wrap(fy, h), y1 = clamp_t ? clamp(fy + 1.f, h) : wrap(fy + 1.f, h);
  return (1.f - tx) * (1.f - ty) * image->at(x0, y0) + tx * (1.f - ty) * image->at(x1, y0) +
         (1.f - tx) * ty * image->at(x0, y1) + tx * ty * image->at(x1, y1);
}

}  // namespace tessera
