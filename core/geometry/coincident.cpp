#include "core/geometry/coincident.h"

#include <algorithm>
#include <array>
#include <bit>
#include <unordered_map>

namespace tessera {

namespace {

using Key = std::array<uint32_t, 9>;

uint32_t bits(float f) { return std::bit_cast<uint32_t>(f == 0.f ? 0.f : f); }  // -0 == +0

Key key_of(const Triangle& t) {
  std::array<std::array<uint32_t, 3>, 3> v = {{{bits(t.p0.x), bits(t.p0.y), bits(t.p0.z)},
                                               {bits(t.p1.x), bits(t.p1.y), bits(t.p1.z)},
                                               {bits(t.p2.x), bits(t.p2.y), bits(t.p2.z)}}};
  std::sort(v.begin(), v.end());
  Key k;
  for (size_t i = 0; i < 3; ++i)
    for (size_t j = 0; j < 3; ++j) k[3 * i + j] = v[i][j];
  return k;
}

struct KeyHash {
  size_t operator()(const Key& k) const {
    uint64_t h = 0xcbf29ce484222325ULL;
    for (uint32_t w : k) h = (h ^ w) * 0x100000001b3ULL;
    return size_t(h ^ (h >> 29));
  }
};

}  // namespace

std::vector<CoincidentPair> find_coincident_triangles(std::span<const Triangle> triangles) {
  std::unordered_map<Key, uint32_t, KeyHash> first;
  first.reserve(triangles.size());
  std::vector<CoincidentPair> out;
  for (uint32_t i = 0; i < uint32_t(triangles.size()); ++i) {
    const auto [it, inserted] = first.emplace(key_of(triangles[i]), i);
    if (!inserted) out.push_back({it->second, i});
  }
  return out;
}

}  // namespace tessera
