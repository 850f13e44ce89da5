// Per-pixel error estimates and the stopping rule of adaptive sampling (`--target-error`).
#pragma once

#include "core/math.h"

#include <cstdint>

namespace tessera {

/// A pixel's estimate: mean, variance of the mean (sample variance / n) and sample count.
struct PixelEstimate {
  Vec3 mean{0.f};      ///< Average of the samples.
  Vec3 var_mean{0.f};  ///< Sample variance divided by the sample count (0 for fewer than two samples).
  uint32_t spp = 0;    ///< Samples taken.
};

/// When adaptive sampling stops: rounds of min_spp, 2 min_spp, 4 min_spp, ... samples (capped at max_spp) until
/// the relative standard error of the luminance mean, sqrt(var_mean(Y)) / max(mean(Y), error_floor), is at most
/// target_error.
struct AdaptiveOptions {
  float target_error = 0.05f;  ///< Relative standard error to reach (> 0).
  uint32_t min_spp = 16;       ///< Samples of the first round (at least 2 so a variance exists).
  uint32_t max_spp = 1024;     ///< Cap on a pixel's samples.
  float error_floor = 0.01f;   ///< Luminance floor of the denominator (dark pixels are judged by absolute error).
};

/// Running sums of a pixel's samples, in double precision and in sample order (so the result is a pure function of
/// the samples), for RGB and for luminance.
class PixelAccumulator {
 public:
  /// Adds one sample.
  void add(const Vec3& L);
  /// Samples added so far.
  uint32_t count() const { return n_; }
  /// Mean, variance of the mean and count.
  PixelEstimate estimate() const;
  /// Relative standard error of the luminance mean: sqrt(var_mean(Y)) / max(mean(Y), floor); 0 below two samples.
  double relative_error(double floor) const;

 private:
  glm::dvec3 sum_{0.0}, sum2_{0.0};
  double y_sum_ = 0.0, y_sum2_ = 0.0;
  uint32_t n_ = 0;
};

/// The sample count of the round after one that ended with `n` samples (doubling, capped at max_spp).
inline uint32_t next_round(uint32_t n, uint32_t max_spp) { return n >= max_spp / 2 ? max_spp : 2 * n; }

}  // namespace tessera
