// Sampler tests: a pixel's samples are a pure function of (seed, x, y, sample index, dimension), any power-of-two
// count of a pixel's samples is stratified (one point per elementary interval in every 2D draw, paired draws
// included), and a draw paired with the one before it is stratified jointly with it (a 4D net).
#include "core/sampling/sampler.h"

#include <gtest/gtest.h>

#include <bit>
#include <functional>
#include <map>
#include <set>
#include <tuple>
#include <vector>

namespace tessera {
namespace {

// The first `dims` values (2D draws flattened) of sample `index` of pixel (x, y).
std::vector<float> stream(uint64_t seed, int x, int y, uint32_t index, int draws) {
  PixelSampler s(seed, x, y, index);
  std::vector<float> v;
  for (int d = 0; d < draws; ++d) {
    const Vec2 u = s.next_2d();
    v.push_back(u.x);
    v.push_back(u.y);
    v.push_back(s.next_1d());
  }
  return v;
}

TEST(PixelSampler, PureFunctionOfSeedPixelIndexAndDimension) {
  const auto a = stream(42, 3, 5, 7, 4);
  EXPECT_EQ(a, stream(42, 3, 5, 7, 4));
  // Interleaving other streams in between does not matter (no hidden state).
  PixelSampler other(1, 2, 3, 4);
  other.next_2d();
  EXPECT_EQ(a, stream(42, 3, 5, 7, 4));
  // Each argument changes the stream.
  EXPECT_NE(a, stream(43, 3, 5, 7, 4));
  EXPECT_NE(a, stream(42, 4, 5, 7, 4));
  EXPECT_NE(a, stream(42, 3, 6, 7, 4));
  EXPECT_NE(a, stream(42, 3, 5, 8, 4));
  EXPECT_NE(a, stream(42 + (uint64_t(1) << 32), 3, 5, 7, 4));  // the seed's high word counts too
  for (float v : a) {
    EXPECT_GE(v, 0.f);
    EXPECT_LT(v, 1.f);
  }
}

// True when the points form a (0, m, 2)-net: every elementary box of area 1/n holds exactly one point.
bool is_net(const std::vector<Vec2>& pts) {
  const size_t n = pts.size();
  int m = 0;
  while ((size_t(1) << m) < n) ++m;
  for (int a = 0; a <= m; ++a) {
    const uint32_t nx = 1u << a, ny = 1u << (m - a);
    std::set<uint32_t> cells;
    for (const Vec2& p : pts) cells.insert(uint32_t(p.x * float(nx)) * ny + uint32_t(p.y * float(ny)));
    if (cells.size() != n) return false;
  }
  return true;
}

// A sampler reading its seeds from the pixel's table (filled by whichever sample first draws a dimension, as
// PixelSampler draws of any kind, paired ones included, past the table's end too) draws bitwise what one hashing per
// draw does.
TEST(PixelSampler, SeedTableGivesBitwiseTheSameDraws) {
  const uint32_t key = PixelSampler::pixel_key(0x1234567890abcdefULL, 17, 5);
  PixelSeeds table(key);
  for (uint32_t index = 0; index < 40; ++index) {
    PixelSampler hashed(key, index), cached(table, index);
    // Each sample takes another mix of draws, so that a dimension is first filled by any kind of draw.
    const uint32_t draws = PixelSeeds::kDims + 20 - index % 7;
    for (uint32_t d = 0; d < draws; ++d) {
      const uint32_t kind = (d * 7 + index) % 4;
      if (kind == 0) {
        const float a = hashed.next_1d(), b = cached.next_1d();
        ASSERT_EQ(std::bit_cast<uint32_t>(a), std::bit_cast<uint32_t>(b)) << index << " " << d;
      } else {
        const Vec2 a = kind == 1 ? hashed.next_2d() : kind == 2 ? hashed.next_2d_paired() : hashed.skip_2d();
        const Vec2 b = kind == 1 ? cached.next_2d() : kind == 2 ? cached.next_2d_paired() : cached.skip_2d();
        ASSERT_EQ(std::bit_cast<uint32_t>(a.x), std::bit_cast<uint32_t>(b.x)) << index << " " << d;
        ASSERT_EQ(std::bit_cast<uint32_t>(a.y), std::bit_cast<uint32_t>(b.y)) << index << " " << d;
      }
    }
  }
}

TEST(PixelSampler, PowerOfTwoSampleCountsAreStratifiedInEveryDraw) {
  for (uint32_t spp : {4u, 16u, 64u, 256u}) {
    for (int px : {0, 17}) {
      constexpr int kDraws = 4;
      std::vector<std::vector<Vec2>> draws(kDraws);
      std::vector<std::vector<float>> ones(kDraws);
      for (uint32_t i = 0; i < spp; ++i) {
        PixelSampler s(9, px, 3, i);
        for (int d = 0; d < kDraws; ++d) {
          draws[size_t(d)].push_back(s.next_2d());
          ones[size_t(d)].push_back(s.next_1d());
        }
      }
      for (int d = 0; d < kDraws; ++d) {
        EXPECT_TRUE(is_net(draws[size_t(d)])) << "spp " << spp << " draw " << d;
        std::set<uint32_t> strata;
        for (float v : ones[size_t(d)]) strata.insert(uint32_t(v * float(spp)));
        EXPECT_EQ(strata.size(), spp) << "1D draw " << d;
      }
    }
  }
}

TEST(PixelSampler, FastSecondDimensionIsThePascalMatrix) {
  // sobol1_reversed(i) bit r = parity of the bits c of i with binomial(c, r) odd, by definition (column by column).
  uint32_t i = 1;
  for (int k = 0; k < 20000; ++k, i = hash_u32(i) >> (k % 32)) {
    uint32_t want = 0;
    for (int c = 0; c < 32; ++c) {
      if (!(i >> c & 1U)) continue;
      uint32_t column = 0;
      for (int r = 0; r <= c; ++r) {
        uint64_t binom = 1;  // binomial(c, r) mod 2 by the recurrence over rows, kept small
        for (int j = 0; j < r; ++j) binom = binom * uint64_t(c - j) / uint64_t(j + 1);
        if (binom & 1U) column |= 1U << r;
      }
      want ^= column;
    }
    EXPECT_EQ(sobol1_reversed(i), want) << i;
  }
  EXPECT_EQ(reverse_bits(0x12345678U), 0x1e6a2c48U);
}

TEST(PixelSampler, DrawsAreDecorrelated) {
  // The 2D draws of one pixel are scrambled independently: the same sample index gives different points per draw.
  PixelSampler s(1, 0, 0, 0);
  const Vec2 a = s.next_2d(), b = s.next_2d();
  EXPECT_NE(a, b);
}

// True when the points (the concatenated coordinates of a pixel's samples) form a (t, m, d)-net: every elementary box
// of volume 2^(t - m) holds exactly 2^t points.
bool is_t_net(const std::vector<std::vector<float>>& pts, int t) {
  const size_t n = pts.size(), d = pts[0].size();
  int m = 0;
  while ((size_t(1) << m) < n) ++m;
  if (t > m) return true;
  std::vector<int> bits(d, 0);  // digits per coordinate, summing to m - t
  std::function<bool(size_t, int)> each = [&](size_t k, int left) {
    if (k + 1 == d) {
      bits[k] = left;
      std::map<uint64_t, int> count;
      for (const auto& p : pts) {
        uint64_t key = 0;
        for (size_t c = 0; c < d; ++c) key = (key << bits[c]) | uint64_t(p[c] * float(1u << bits[c]));
        ++count[key];
      }
      if (count.size() != (size_t(1) << (m - t))) return false;
      for (const auto& [key, c] : count)
        if (c != (1 << t)) return false;
      return true;
    }
    for (int b = 0; b <= left; ++b) {
      bits[k] = b;
      if (!each(k + 1, left - b)) return false;
    }
    return true;
  };
  return each(0, m - t);
}

// The 2D draw and the paired draw of samples [first, first + count) of a pixel, as 4D points.
std::vector<std::vector<float>> paired_points(uint64_t seed, int px, uint32_t first, uint32_t count, bool paired) {
  std::vector<std::vector<float>> pts;
  for (uint32_t i = first; i < first + count; ++i) {
    PixelSampler s(seed, px, 4, i);
    const Vec2 a = s.next_2d();
    s.next_1d();  // a 1D draw in between does not matter
    const Vec2 b = paired ? s.next_2d_paired() : s.next_2d();
    pts.push_back({a.x, a.y, b.x, b.y});
  }
  return pts;
}

TEST(PixelSampler, PairedDrawIsAStratifiedDrawOnItsOwn) {
  // Prefixes and aligned blocks (e.g. samples 48..63 of 64) of the paired draw are (0, m, 2)-nets.
  for (uint32_t block : {4u, 16u, 64u, 256u})
    for (uint32_t first : {0u, block, 3 * block}) {
      std::vector<Vec2> light;
      for (const auto& p : paired_points(21, 3, first, block, true)) light.push_back({p[2], p[3]});
      EXPECT_TRUE(is_net(light)) << block << " samples from " << first;
    }
  // Without a 2D draw before it, a paired draw is a plain one.
  PixelSampler a(1, 2, 3, 4), b(1, 2, 3, 4);
  EXPECT_EQ(a.next_2d_paired(), b.next_2d());
  EXPECT_EQ(a.next_2d(), b.next_2d());
}

TEST(PixelSampler, PairedDrawsFormAFourDimensionalNet) {
  // kPairColumns' t-values (see its comment): t <= 3 in 4D up to 8192 points; every projection that mixes the two
  // draws is at least as good. Random pairing (two independent draws) is no (3, m, 4)-net from 64 points on.
  for (uint32_t n = 4; n <= 1024; n *= 4)
    for (uint32_t first : {0u, n}) {
      const auto pts = paired_points(17, 9, first, n, true);
      EXPECT_TRUE(is_t_net(pts, 3)) << n << " samples from " << first;
      for (const auto& [a, b, c] : {std::tuple{0, 2, 3}, {1, 2, 3}, {0, 1, 2}, {0, 1, 3}}) {
        std::vector<std::vector<float>> proj;
        for (const auto& p : pts) proj.push_back({p[size_t(a)], p[size_t(b)], p[size_t(c)]});
        EXPECT_TRUE(is_t_net(proj, 3)) << n << " samples, projection " << a << b << c;
      }
    }
  EXPECT_FALSE(is_t_net(paired_points(17, 9, 0, 256, false), 3));
}

// pair_index maps each aligned block of 2^m indices onto an aligned block, one to one.
TEST(PixelSampler, PairIndexPermutesAlignedBlocks) {
  for (int m : {0, 3, 8}) {
    for (uint32_t block : {0u, 5u, 0x12345u}) {
      std::set<uint32_t> image;
      const uint32_t first = block << m;
      for (uint32_t i = first; i < first + (1u << m); ++i) image.insert(pair_index(i));
      EXPECT_EQ(image.size(), size_t(1) << m);
      EXPECT_EQ(*image.rbegin() - *image.begin(), (1u << m) - 1) << m;  // a whole aligned block
      EXPECT_EQ(*image.begin() % (1u << m), 0u) << m;
    }
  }
}

// Mean squared error of a pixel's n-sample estimate of f over the first two 2D draws, over kSeeds seeds.
double pixel_mse(const std::function<double(Vec2, Vec2)>& f, double exact, uint32_t n) {
  constexpr int kSeeds = 4096;
  double mse = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    double sum = 0;
    for (uint32_t i = 0; i < n; ++i) {
      PixelSampler s(uint64_t(seed), 5, 7, i);
      const Vec2 u = s.next_2d(), v = s.next_2d();
      sum += f(u, v);
    }
    const double d = sum / double(n) - exact;
    mse += d * d / kSeeds;
  }
  return mse;
}

// The expected error falls with the sample count (a few renders of cbox_area_light hitting a rare sliver of its light
// can make one spp's relMSE exceed a lower spp's; that is the scene, not the sampler, and this pins the sampler
// side). Integrands like a pixel's: a rare bright sliver (a light seen edge-on in a corner of the pixel), a
// slanted edge times a light's visibility, and a smooth shading term. Doubling n must cut the error by at least 0.6
// (i.i.d. sampling: 0.5; stratification: less); between powers of two the discontinuous integrands still decrease.
// A smooth integrand does not: a count between two powers of two can be worse than the lower one (16 -> 24 spp:
// 1.08x), because the extra samples are half of the next stratified block.
TEST(PixelSampler, ExpectedErrorDecreasesWithSampleCount) {
  struct Case {
    const char* name;
    std::function<double(Vec2, Vec2)> f;
    double exact;
    bool discontinuous;
  };
  const Case cases[] = {
      {"sliver", [](Vec2 u, Vec2) { return u.x + u.y < 0.1f ? 28.0 : 0.0; }, 28.0 * 0.005, true},
      {"edge x visibility",
       [](Vec2 u, Vec2 v) { return (u.y < 0.3f + 0.4f * u.x ? 1.0 : 0.0) * (v.x < 0.5f + 0.2f * v.y ? 1.0 : 0.0); },
       0.5 * 0.6, true},
      {"smooth", [](Vec2 u, Vec2 v) { return double(u.x) * double(u.y) + double(v.x) * double(v.x); },
       0.25 + 1.0 / 3.0, false},
  };
  for (const Case& c : cases) {
    double previous_power = 0;
    for (uint32_t n = 4; n <= 64; n *= 2) {
      const double mse = pixel_mse(c.f, c.exact, n);
      if (previous_power > 0) {
        EXPECT_LT(mse, 0.6 * previous_power) << c.name << " at " << n << " spp";
      }
      if (c.discontinuous && n < 64) {
        const double between = pixel_mse(c.f, c.exact, n + n / 2);
        EXPECT_LT(between, mse) << c.name << " at " << n + n / 2 << " spp";
        EXPECT_GT(between, pixel_mse(c.f, c.exact, 2 * n)) << c.name << " at " << n + n / 2 << " spp";
      }
      previous_power = mse;
    }
  }
}

// A penumbra: a pixel whose visibility edge, in the light's coordinates, moves with the position in the pixel (a
// shadow boundary crossing the pixel). Pairing the light draw with the pixel draw stratifies the two jointly.
TEST(PixelSampler, PairedDrawLowersTheErrorOfAPenumbra) {
  const auto f = [](Vec2 p, Vec2 l) { return l.x < 0.2f + 0.6f * p.x + 0.1f * l.y ? 1.0 : 0.0; };
  const double exact = 0.2 + 0.3 + 0.05;
  constexpr int kSeeds = 2048;
  for (uint32_t n : {16u, 64u, 256u}) {
    double mse[2] = {0, 0};
    for (int paired = 0; paired < 2; ++paired)
      for (int seed = 0; seed < kSeeds; ++seed) {
        double sum = 0;
        for (uint32_t i = 0; i < n; ++i) {
          PixelSampler s(uint64_t(seed), 1, 2, i);
          const Vec2 p = s.next_2d();
          sum += f(p, paired ? s.next_2d_paired() : s.next_2d());
        }
        const double d = sum / double(n) - exact;
        mse[paired] += d * d / kSeeds;
      }
    std::printf("%u samples: MSE random pairing %.3e, paired %.3e (%.2fx)\n", n, mse[0], mse[1], mse[0] / mse[1]);
    EXPECT_LT(mse[1], 0.7 * mse[0]) << n;  // measured 1.84x, 1.70x, 5.40x
  }
}

}  // namespace
}  // namespace tessera
