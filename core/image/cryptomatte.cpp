#include "core/image/cryptomatte.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstring>

namespace tessera {

namespace {

uint32_t rotl32(uint32_t x, int r) { return (x << r) | (x >> (32 - r)); }

std::string hex8(uint32_t v) {
  char buf[9];
  std::snprintf(buf, sizeof buf, "%08x", v);
  return buf;
}

}  // namespace

uint32_t murmur3_32(std::string_view bytes) {
  const uint32_t c1 = 0xcc9e2d51, c2 = 0x1b873593;
  uint32_t h = 0;
  const size_t blocks = bytes.size() / 4;
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  for (size_t i = 0; i < blocks; ++i) {
    uint32_t k = uint32_t(p[4 * i]) | uint32_t(p[4 * i + 1]) << 8 | uint32_t(p[4 * i + 2]) << 16 |
                 uint32_t(p[4 * i + 3]) << 24;
    k *= c1;
    k = rotl32(k, 15);
    k *= c2;
    h ^= k;
    h = rotl32(h, 13);
    h = h * 5 + 0xe6546b64;
  }
  const unsigned char* tail = p + 4 * blocks;
  uint32_t k = 0;
  switch (bytes.size() & 3) {
    case 3: k ^= uint32_t(tail[2]) << 16; [[fallthrough]];
    case 2: k ^= uint32_t(tail[1]) << 8; [[fallthrough]];
    case 1:
      k ^= tail[0];
      k *= c1;
      k = rotl32(k, 15);
      k *= c2;
      h ^= k;
  }
  h ^= uint32_t(bytes.size());
  h ^= h >> 16;
  h *= 0x85ebca6b;
  h ^= h >> 13;
  h *= 0xc2b2ae35;
  h ^= h >> 16;
  return h;
}

uint32_t cryptomatte_id(std::string_view name) {
  uint32_t h = murmur3_32(name);
  const uint32_t exponent = (h >> 23) & 0xffu;
  if (exponent == 0 || exponent == 0xffu) h ^= 1u << 23;
  return h;
}

float cryptomatte_float(uint32_t id) {
  float f;
  std::memcpy(&f, &id, sizeof f);
  return f;
}

std::map<std::string, std::string> cryptomatte_metadata(std::string_view layer, const std::vector<std::string>& names) {
  nlohmann::json manifest = nlohmann::json::object();
  for (const std::string& n : names) manifest[n] = hex8(cryptomatte_id(n));
  const std::string prefix = "cryptomatte/" + hex8(murmur3_32(layer)).substr(0, 7) + "/";
  return {{prefix + "name", std::string(layer)},
          {prefix + "hash", "MurmurHash3_32"},
          {prefix + "conversion", "uint32_to_float32"},
          {prefix + "manifest", manifest.dump()}};
}

}  // namespace tessera
