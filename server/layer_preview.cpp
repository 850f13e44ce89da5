#include "server/layer_preview.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace tessera::server {

namespace {

// A bright, stable colour for an integer id or a Cryptomatte id's bits (0: black).
Vec3 id_colour(uint32_t id) {
  if (id == 0) return Vec3(0.f);
  uint32_t h = id * 0x9E3779B1u;
  h ^= h >> 15;
  h *= 0x85EBCA77u;
  h ^= h >> 13;
  return Vec3(0.2f + 0.8f * float(h & 0xffu) / 255.f, 0.2f + 0.8f * float((h >> 8) & 0xffu) / 255.f,
              0.2f + 0.8f * float((h >> 16) & 0xffu) / 255.f);
}

float largest_finite(const std::vector<const std::vector<float>*>& chans, bool absolute) {
  float m = 0.f;
  for (const auto* c : chans)
    for (const float v : *c)
      if (std::isfinite(v)) m = std::max(m, absolute ? std::abs(v) : v);
  return m > 0.f ? m : 1.f;
}

}  // namespace

Image layer_display(const Image& img, Layer layer) {
  const std::vector<std::string> names = layer_channels(layer);
  std::vector<const std::vector<float>*> ch;
  for (const std::string& n : names) {
    const auto it = img.extra.find(n);
    if (it == img.extra.end()) throw std::invalid_argument("the image has no channel " + n);
    ch.push_back(&it->second);
  }
  Image out = Image::make(img.width, img.height);
  const size_t n = size_t(img.width) * size_t(img.height);
  const auto rgb = [&](size_t i, const Vec3& c) {
    out.rgb[3 * i] = c.x;
    out.rgb[3 * i + 1] = c.y;
    out.rgb[3 * i + 2] = c.z;
  };
  const auto v3 = [&](size_t i) { return Vec3((*ch[0])[i], (*ch[1])[i], (*ch[2])[i]); };
  switch (layer) {
    case Layer::kAlbedo:
      for (size_t i = 0; i < n; ++i) rgb(i, v3(i));
      break;
    case Layer::kNormal:
      for (size_t i = 0; i < n; ++i) rgb(i, 0.5f + 0.5f * v3(i));
      break;
    case Layer::kPosition: {
      const float m = largest_finite(ch, true);
      for (size_t i = 0; i < n; ++i) rgb(i, 0.5f + 0.5f * v3(i) / m);
      break;
    }
    case Layer::kDepth: {
      const float m = largest_finite(ch, false);
      for (size_t i = 0; i < n; ++i) {
        const float z = (*ch[0])[i];
        rgb(i, Vec3(std::isfinite(z) ? 1.f - z / m : 0.f));
      }
      break;
    }
    case Layer::kMaterialId:
    case Layer::kObjectId:
      for (size_t i = 0; i < n; ++i) rgb(i, id_colour(uint32_t((*ch[0])[i])));
      break;
    case Layer::kVariance: {
      const float m = std::sqrt(largest_finite({ch[0], ch[1], ch[2]}, false));
      for (size_t i = 0; i < n; ++i)
        rgb(i, Vec3(std::sqrt(std::max(0.f, (*ch[0])[i])), std::sqrt(std::max(0.f, (*ch[1])[i])),
                    std::sqrt(std::max(0.f, (*ch[2])[i]))) / m);
      break;
    }
    case Layer::kCryptoMaterial:
    case Layer::kCryptoObject:
      for (size_t i = 0; i < n; ++i) {
        uint32_t bits;
        std::memcpy(&bits, &(*ch[0])[i], sizeof bits);
        rgb(i, id_colour(bits) * (*ch[1])[i]);
      }
      break;
  }
  return out;
}

}  // namespace tessera::server
