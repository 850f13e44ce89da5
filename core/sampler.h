// Deterministic per-pixel sample streams: Owen-scrambled Sobol points, a pure function of
// (seed, pixel x, pixel y, sample index, dimension), so a pixel's value never depends on tiling or threads.
#pragma once

#include "core/math.h"

#include <cstdint>

namespace tessera {

/// 32-bit integer hash with good avalanche (a murmur3-style finaliser).
constexpr uint32_t hash_u32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

/// Combines several values into one hash, order-sensitive.
constexpr uint32_t hash_combine(uint32_t seed, uint32_t v) { return hash_u32(seed ^ (v + 0x9e3779b9U + (seed << 6) + (seed >> 2))); }

/// Reverses the bit order of a 32-bit word.
constexpr uint32_t reverse_bits(uint32_t x) {
  x = __builtin_bswap32(x);
  x = ((x >> 4) & 0x0f0f0f0fU) | ((x & 0x0f0f0f0fU) << 4);
  x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
  return ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
}

/// The Laine-Karras permutation (Burley 2020) of a bit-reversed value: each bit is flipped by a hash of the bits
/// below it, which in reversed order are the bits above it.
constexpr uint32_t laine_karras(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cU;
  x ^= x * 0xb82f1e52U;
  x ^= x * 0xc7afe638U;
  x ^= x * 0x8d22f6e6U;
  return x;
}

/// Nested uniform (Owen) scrambling of a 32-bit fixed-point value, as a hash applied in reversed bit order
/// (Laine-Karras permutation, Burley 2020): each bit is flipped by a hash of the bits above it.
constexpr uint32_t owen_scramble(uint32_t x, uint32_t seed) { return reverse_bits(laine_karras(reverse_bits(x), seed)); }

/// The second dimension of the (0,2)-sequence (Sobol dimension 1, the Pascal matrix mod 2) at index i, in reversed
/// bit order: digit r (weight 2^-(r+1)) is bit r, the parity of the set bits c of i whose positions contain r's
/// (binomial(c, r) odd, by Lucas' theorem): a superset-parity transform over the five bits of the bit position.
constexpr uint32_t sobol1_reversed(uint32_t i) {
  i ^= (i >> 1) & 0x55555555U;
  i ^= (i >> 2) & 0x33333333U;
  i ^= (i >> 4) & 0x0f0f0f0fU;
  i ^= (i >> 8) & 0x00ff00ffU;
  return i ^ (i >> 16);
}

/// 32-bit fixed point to a float in [0, 1).
inline float u32_to_unit(uint32_t x) { return std::min(float(x) * 0x1p-32f, 0x1.fffffep-1f); }

/// One pixel sample's stream of random dimensions. Each 2D draw is a shuffled, Owen-scrambled point of the
/// (0,2)-sequence made of the first two Sobol dimensions, so any power-of-two prefix of a pixel's samples is
/// stratified in every 2D projection; different draws are decorrelated by hashing the dimension index.
class PixelSampler {
 public:
  /// The stream for sample `index` of pixel (px, py) under `seed`.
  PixelSampler(uint64_t seed, int px, int py, uint32_t index)
      : key_(hash_combine(hash_combine(hash_combine(uint32_t(seed), uint32_t(seed >> 32)), uint32_t(px)), uint32_t(py))),
        index_(index) {}

  /// Next 2D sample in [0,1)^2.
  Vec2 next_2d() {
    const uint32_t dim_seed = hash_combine(key_, dim_++);
    const uint32_t i = owen_scramble(index_, hash_u32(dim_seed));  // shuffle the sample order per dimension
    // Sobol dimension 0 (van der Corput: the reversed index) and dimension 1, each Owen-scrambled; both are built in
    // reversed bit order, where the scramble works, and reversed once.
    const uint32_t x = reverse_bits(laine_karras(i, hash_combine(dim_seed, 0x51ed27U)));
    const uint32_t y = reverse_bits(laine_karras(sobol1_reversed(i), hash_combine(dim_seed, 0x2f1c9dU)));
    return {u32_to_unit(x), u32_to_unit(y)};
  }

  /// Next 1D sample in [0,1).
  float next_1d() {
    const uint32_t dim_seed = hash_combine(key_, dim_++);
    const uint32_t i = owen_scramble(index_, hash_u32(dim_seed));
    return u32_to_unit(reverse_bits(laine_karras(i, hash_combine(dim_seed, 0x7a3b1U))));
  }

 private:
  uint32_t key_;
  uint32_t index_;
  uint32_t dim_ = 0;
};

}  // namespace tessera
