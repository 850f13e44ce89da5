// Deterministic per-pixel sample streams: Owen-scrambled Sobol points, a pure function of
// (seed, pixel x, pixel y, sample index, dimension), so a pixel's value never depends on tiling or threads.
#pragma once

#include "core/util/math.h"

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
/// below it, which in reversed order are the bits above it. reverse_bits(laine_karras(reverse_bits(x), seed)) is a
/// nested uniform (Owen) scrambling of the fixed-point value x.
constexpr uint32_t laine_karras(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cU;
  x ^= x * 0xb82f1e52U;
  x ^= x * 0xc7afe638U;
  x ^= x * 0x8d22f6e6U;
  return x;
}

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

/// Columns of the index map that pairs a 2D draw with the one before it (PixelSampler::next_2d_paired): column c
/// is the image of index bit c. Each column holds its own bit and only lower ones (a unit upper triangular matrix
/// over GF(2)), so the map permutes every aligned block of 2^m indices onto an aligned block, the halves of a block
/// onto the halves of its image. Chosen column by column by a beam search over the t-values of the four-dimensional
/// net (draw, paired draw) and of its projections that mix the two draws (weighting most the 3D ones made of one
/// coordinate of the first draw and both of the paired one): for 4 to 8192 points t <= 3 in 4D and in every such
/// projection (t = 4 at 16384), about as good as Owen-scrambled Sobol dimensions 0-3, whose last two are no
/// (0,2)-sequence; random pairing is no net at all. Columns past the search are the identity.
inline constexpr uint32_t kPairColumns[32] = {
    0x1,      0x2,      0x5,      0xb,      0x1a,     0x2b,     0x49,     0x84,     0x1a3,    0x3e9,    0x412,
    0xc4d,    0x11bb,   1U << 13, 1U << 14, 1U << 15, 1U << 16, 1U << 17, 1U << 18, 1U << 19, 1U << 20, 1U << 21,
    1U << 22, 1U << 23, 1U << 24, 1U << 25, 1U << 26, 1U << 27, 1U << 28, 1U << 29, 1U << 30, 1U << 31};

namespace detail {

// kPairColumns as four byte-indexed tables: the image of byte k of an index with value b is table[k][b].
struct PairTables {
  uint32_t table[4][256];
};

constexpr PairTables make_pair_tables() {
  PairTables t{};
  for (int k = 0; k < 4; ++k)
    for (uint32_t b = 0; b < 256; ++b) {
      uint32_t v = 0;
      for (int c = 0; c < 8; ++c)
        if (b >> c & 1U) v ^= kPairColumns[8 * k + c];
      t.table[k][b] = v;
    }
  return t;
}

inline constexpr PairTables kPairTables = make_pair_tables();

}  // namespace detail

/// The index map of kPairColumns (a GF(2)-linear bijection of 32-bit indices).
constexpr uint32_t pair_index(uint32_t i) {
  const auto& t = detail::kPairTables.table;
  return t[0][i & 0xffU] ^ t[1][(i >> 8) & 0xffU] ^ t[2][(i >> 16) & 0xffU] ^ t[3][i >> 24];
}

/// 32-bit fixed point to a float in [0, 1).
inline float u32_to_unit(uint32_t x) { return std::min(float(x) * 0x1p-32f, 0x1.fffffep-1f); }

/// The scramble seeds of one dimension of a pixel's sample streams, all derived from dim_seed = hash_combine(key,
/// dim): the index shuffle, the 2D draw's two coordinates and the 1D draw. Every sample of the pixel uses the same.
struct DimSeeds {
  uint32_t shuffle;  ///< hash_u32(dim_seed): the sample order's scramble.
  uint32_t x, y;     ///< The 2D draw's scrambles: hash_combine(dim_seed, 0x51ed27U), hash_combine(dim_seed, 0x2f1c9dU).
  uint32_t one;      ///< The 1D draw's scramble: hash_combine(dim_seed, 0x7a3b1U).

  /// The seeds of dimension dim of the streams of pixel key `key`.
  static constexpr DimSeeds of(uint32_t key, uint32_t dim) {
    const uint32_t dim_seed = hash_combine(key, dim);
    return {hash_u32(dim_seed), hash_combine(dim_seed, 0x51ed27U), hash_combine(dim_seed, 0x2f1c9dU),
            hash_combine(dim_seed, 0x7a3b1U)};
  }
};

/// The DimSeeds of one pixel key's first kDims dimensions, each hashed when a sample first draws it and then read by
/// every later sample of the pixel (a PixelSampler made with the table): the same values as hashing them per draw,
/// for a fraction of the work when a pixel takes many samples. One table serves one thread.
class PixelSeeds {
 public:
  /// Dimensions kept; later ones are hashed per draw.
  static constexpr uint32_t kDims = 96;

  /// An empty table for pixel key `key` (PixelSampler::pixel_key).
  explicit PixelSeeds(uint32_t key) : key_(key) {}

  /// The pixel key.
  uint32_t key() const { return key_; }

  /// The seeds of dimension dim.
  const DimSeeds& at(uint32_t dim) {
    if (dim >= filled_) [[unlikely]] fill(dim);
    return seeds_[dim];
  }

 private:
  void fill(uint32_t dim) {
    for (; filled_ <= dim; ++filled_) seeds_[filled_] = DimSeeds::of(key_, filled_);
  }

  uint32_t key_;
  uint32_t filled_ = 0;  // dimensions [0, filled_) hold their seeds
  DimSeeds seeds_[kDims];
};

/// One pixel sample's stream of random dimensions. Each 2D draw is a shuffled, Owen-scrambled point of the
/// (0,2)-sequence made of the first two Sobol dimensions, so any power-of-two prefix of a pixel's samples (indeed
/// any aligned power-of-two block of them) is stratified in every 2D projection; different draws are decorrelated
/// by hashing the dimension index, except that a paired draw (next_2d_paired) is stratified jointly with the draw
/// before it.
class PixelSampler {
 public:
  /// The stream for sample `index` of pixel (px, py) under `seed`.
  PixelSampler(uint64_t seed, int px, int py, uint32_t index) : PixelSampler(pixel_key(seed, px, py), index) {}

  /// The same stream from the pixel's key, pixel_key(seed, px, py), hashed once for all the pixel's samples.
  PixelSampler(uint32_t key, uint32_t index) : key_(key), reversed_index_(reverse_bits(index)) {}

  /// The same stream, reading its dimensions' seeds from the pixel's table (the same values) and filling it; the
  /// table must outlive the sampler.
  PixelSampler(PixelSeeds& seeds, uint32_t index)
      : key_(seeds.key()), reversed_index_(reverse_bits(index)), table_(&seeds) {}

  /// The hash of (seed, px, py) that every sample stream of the pixel starts from.
  static constexpr uint32_t pixel_key(uint64_t seed, int px, int py) {
    return hash_combine(hash_combine(hash_combine(uint32_t(seed), uint32_t(seed >> 32)), uint32_t(px)), uint32_t(py));
  }

  /// Next 2D sample in [0,1)^2.
  Vec2 next_2d() {
    const DimSeeds d = seeds(dim_++);
    // Shuffle the sample order per dimension: the index Owen-scrambled, starting from its reversed bits.
    last_index_ = reverse_bits(laine_karras(reversed_index_, d.shuffle));
    has_last_ = true;
    return point_2d(last_index_, d);
  }

  /// Next 2D sample in [0,1)^2, stratified jointly with this sample's previous next_2d() draw: the point of index
  /// pair_index(i) of the (0,2)-sequence, i being that draw's shuffled index, with scrambles of its own. Over a
  /// pixel's samples the two draws form a four-dimensional Owen-scrambled digital net (t-values at kPairColumns), so
  /// e.g. a pixel position and a point on a light are stratified together instead of paired at random; on its own
  /// the paired draw is still a shuffled (0,2)-sequence, stratified in every aligned power-of-two block of samples.
  /// Without a previous next_2d() draw it is one.
  Vec2 next_2d_paired() {
    if (!has_last_) return next_2d();
    return point_2d(pair_index(last_index_), seeds(dim_++));
  }

  /// Skips the next 2D draw (whose value the caller does not need): later draws are those next_2d() would leave.
  Vec2 skip_2d() {
    ++dim_;
    return Vec2(0.f);
  }

  /// Skips the next 1D draw (whose value the caller does not need): later draws are those next_1d() would leave.
  float skip_1d() {
    ++dim_;
    return 0.f;
  }

  /// Next 1D sample in [0,1).
  float next_1d() {
    const DimSeeds d = seeds(dim_++);
    const uint32_t i = reverse_bits(laine_karras(reversed_index_, d.shuffle));
    return u32_to_unit(reverse_bits(laine_karras(i, d.one)));
  }

 private:
  // The seeds of dimension dim: from the pixel's table when there is one and it keeps dim, else hashed here.
  DimSeeds seeds(uint32_t dim) const {
    if (table_ && dim < PixelSeeds::kDims) [[likely]] return table_->at(dim);
    return DimSeeds::of(key_, dim);
  }

  // Point i of the (0,2)-sequence, Owen-scrambled with the dimension's seeds: Sobol dimension 0 (van der Corput, the
  // reversed index) and dimension 1, both built in reversed bit order, where the scramble works, and reversed once.
  static Vec2 point_2d(uint32_t i, const DimSeeds& d) {
    const uint32_t x = reverse_bits(laine_karras(i, d.x));
    const uint32_t y = reverse_bits(laine_karras(sobol1_reversed(i), d.y));
    return {u32_to_unit(x), u32_to_unit(y)};
  }

  uint32_t key_;
  uint32_t reversed_index_;  // the sample index, bit-reversed once for every draw's scrambling
  uint32_t dim_ = 0;
  uint32_t last_index_ = 0;  // shuffled index of the last next_2d() draw
  bool has_last_ = false;
  PixelSeeds* table_ = nullptr;  // the pixel's seed table, if any
};

}  // namespace tessera
