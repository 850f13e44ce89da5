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
  x = ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
  x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
  x = ((x >> 4) & 0x0f0f0f0fU) | ((x & 0x0f0f0f0fU) << 4);
  x = ((x >> 8) & 0x00ff00ffU) | ((x & 0x00ff00ffU) << 8);
  return (x >> 16) | (x << 16);
}

/// The Laine-Karras permutation of a bit-reversed value: owen_scramble without its two reversals.
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

/// Sobol dimension 1 of index i, bit-reversed: the generator matrix is Pascal's triangle mod 2, and applying it is
/// substituting x + 1 for x in the polynomial whose coefficients are i's bits, done on halves of every block of
/// 2, 4, ... 32 bits (equal to the bit-serial loop for all 2^32 indices).
constexpr uint32_t sobol_1_reversed(uint32_t i) {
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
  PixelSampler(uint64_t seed, int px, int py, uint32_t index) : PixelSampler(pixel_key(seed, px, py), index) {}

  /// The same stream from the pixel's key, pixel_key(seed, px, py), hashed once for all the pixel's samples.
  PixelSampler(uint32_t key, uint32_t index) : key_(key), reversed_index_(reverse_bits(index)) {}

  /// The hash of (seed, px, py) that every sample stream of the pixel starts from.
  static constexpr uint32_t pixel_key(uint64_t seed, int px, int py) {
    return hash_combine(hash_combine(hash_combine(uint32_t(seed), uint32_t(seed >> 32)), uint32_t(px)), uint32_t(py));
  }

  /// Next 2D sample in [0,1)^2.
  Vec2 next_2d() {
    const uint32_t dim_seed = hash_combine(key_, dim_++);
    // Shuffle the sample order per dimension: i = owen_scramble(index, hash_u32(dim_seed)).
    const uint32_t i = reverse_bits(laine_karras(reversed_index_, hash_u32(dim_seed)));
    // Sobol dimensions 0 (van der Corput: i reversed) and 1, Owen-scrambled; scrambling starts by reversing the
    // bits, so both are scrambled from their reversed forms.
    const uint32_t x = reverse_bits(laine_karras(i, hash_combine(dim_seed, 0x51ed27U)));
    const uint32_t y = reverse_bits(laine_karras(sobol_1_reversed(i), hash_combine(dim_seed, 0x2f1c9dU)));
    return {u32_to_unit(x), u32_to_unit(y)};
  }

  /// Skips the next 2D draw (whose value the caller does not need): later draws are those next_2d() would leave.
  Vec2 skip_2d() {
    ++dim_;
    return Vec2(0.f);
  }

  /// Next 1D sample in [0,1).
  float next_1d() {
    const uint32_t dim_seed = hash_combine(key_, dim_++);
    const uint32_t i = reverse_bits(laine_karras(reversed_index_, hash_u32(dim_seed)));
    return u32_to_unit(reverse_bits(laine_karras(i, hash_combine(dim_seed, 0x7a3b1U))));
  }

 private:
  uint32_t key_;
  uint32_t reversed_index_;  // the sample index, bit-reversed once for every draw's scrambling
  uint32_t dim_ = 0;
};

}  // namespace tessera
