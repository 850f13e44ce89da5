// Per-pixel error estimates and the stopping rule of adaptive sampling (`--target-error`).
#pragma once

#include "core/util/math.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace tessera {

/// Most independent replicates a pixel's samples can be split into.
inline constexpr uint32_t kMaxReplicates = 16;
/// Default first round of adaptive sampling (`render`, `submit` and farm jobs share it).
inline constexpr uint32_t kAdaptiveMinSpp = 16;
/// Default cap on a pixel's samples under adaptive sampling.
inline constexpr uint32_t kAdaptiveMaxSpp = 1024;

/// A pixel's estimate: mean, variance of the mean and sample count.
struct PixelEstimate {
  Vec3 mean{0.f};      ///< Average of the samples.
  Vec3 var_mean{0.f};  ///< Estimated variance of the mean (see PixelAccumulator; 0 when it cannot be estimated).
  uint32_t spp = 0;    ///< Samples taken.
};

/// When adaptive sampling stops: rounds of min_spp, 2 min_spp, 4 min_spp, ... samples (capped at max_spp) until
/// the pixel's relative error (PixelAccumulator::relative_error) is at most target_error. Because that error is
/// never below 1/n, a pixel takes at least 1/target_error samples even when all of them agree.
struct AdaptiveOptions {
  float target_error = 0.05f;  ///< Relative standard error to reach (> 0).
  uint32_t min_spp = kAdaptiveMinSpp;  ///< Samples of the first round (at least 2 so a variance exists).
  uint32_t max_spp = kAdaptiveMaxSpp;  ///< Cap on a pixel's samples.
  float error_floor = 0.01f;   ///< Luminance floor of the denominator (dark pixels are judged by absolute error).
  uint32_t replicates = 1;     ///< Independent replicates (see PixelAccumulator); rounds are multiples of it.
};

/// Running sums of a pixel's samples, in double precision and in sample order (so the result is a pure function of
/// the samples), for RGB and for luminance. With one replicate the variance of the mean is the i.i.d. estimate
/// (sample variance / n): under the stratified (Owen-scrambled Sobol) sampler the true error is smaller, so it is a
/// conservative bound. With K >= 2 replicates, sample s belongs to replicate s mod K, each replicate being an
/// independently scrambled sequence (see render.h); the variance of the mean is then estimated from the spread of
/// the K replicate means, which is unbiased for randomised QMC (K - 1 degrees of freedom per pixel).
class PixelAccumulator {
 public:
  /// An accumulator for `replicates` interleaved replicates (1..kMaxReplicates).
  explicit PixelAccumulator(uint32_t replicates = 1);
  /// Adds the next sample (sample index count()).
  void add(const Vec3& L);
  /// Samples added so far.
  uint32_t count() const { return n_; }
  /// Mean, variance of the mean and count.
  PixelEstimate estimate() const;
  /// Replicates the samples are split into.
  uint32_t replicates() const { return k_; }
  /// Number of doubles in the exact state of an accumulator with `replicates` replicates (see state_names).
  static size_t state_size(uint32_t replicates);
  /// What each double of the state is, in order: "sum.R", "sum.G", "sum.B", "sum2.R", "sum2.G", "sum2.B", "sum.Y",
  /// "sum2.Y" (sums and sums of squares of the samples and of their luminance) and, with K >= 2 replicates,
  /// "rep0.R", "rep0.G", "rep0.B", "rep0.Y", ... "rep<K-1>.Y" (each replicate's sums).
  static std::vector<std::string> state_names(uint32_t replicates);
  /// Writes the exact state (state_size(replicates()) doubles) to out.
  void save(double* out) const;
  /// The accumulator whose state save() wrote: adding samples count, count + 1, ... to it gives bit for bit what
  /// adding them to the original would have.
  static PixelAccumulator restore(uint32_t replicates, uint32_t count, const double* state);
  /// Relative error of the luminance mean: sqrt(var_mean(Y) + (s / n)^2) / s with s = max(mean(Y), floor). The
  /// (s / n)^2 term stands for what n samples cannot see: an event of probability about 1/n (rule of succession)
  /// at the pixel's own scale moves the mean by about s / n. Without it, a pixel whose first samples all happen
  /// to miss a small light (zero sample variance) would stop at once, however wrong. Infinite below two samples.
  double relative_error(double floor) const;

 private:
  /// Variance of the mean of the values whose sums are sum, sum2 (i.i.d.) or per replicate rep[] (replicates).
  double var_mean(double sum, double sum2, const double* rep) const;

  glm::dvec3 sum_{0.0}, sum2_{0.0};
  double y_sum_ = 0.0, y_sum2_ = 0.0;
  uint32_t n_ = 0;
  uint32_t k_ = 1;
  double rep_[kMaxReplicates][4] = {};  // per replicate: R, G, B, Y sums
};

/// The sample count of the round after one that ended with `n` samples (doubling, capped at max_spp).
inline uint32_t next_round(uint32_t n, uint32_t max_spp) { return n >= max_spp / 2 ? max_spp : 2 * n; }

}  // namespace tessera
