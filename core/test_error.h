// Test-only: comparing a render's measured error against an independent reference with the error the renders
// predict for themselves (their variance-of-the-mean channels), with a tolerance estimated from the data.
#pragma once

#include "core/image.h"

#include <cmath>
#include <numeric>
#include <vector>

namespace tessera::testing {

/// Sums over pixels of the squared relative luminance difference D^2 / (R^2 + 0.01), D = I - R, and of its
/// prediction (Var(I) + Var(R)) / (R^2 + 0.01) (the weights of relMSE, so bright pixels do not dominate).
struct ErrorCheck {
  double measured = 0;   ///< Sum of D^2.
  double predicted = 0;  ///< Sum of the predicted Var(I) + Var(R).
  double sd = 0;         ///< Standard deviation of `measured` as a sum of independent per-pixel terms (from data).
  size_t n = 0;          ///< Pixels.
};

/// Variance of pixel i's luminance mean from its per-channel variance channels, channels treated as fully
/// correlated (exact for grey pixels, an upper bound otherwise).
inline double luminance_variance(const Image& img, size_t i) {
  const double s = 0.2126 * std::sqrt(double(img.extra.at("variance.R")[i])) +
                   0.7152 * std::sqrt(double(img.extra.at("variance.G")[i])) +
                   0.0722 * std::sqrt(double(img.extra.at("variance.B")[i]));
  return s * s;
}

/// Luminance of pixel i.
inline double pixel_luminance(const Image& img, size_t i) {
  return 0.2126 * double(img.rgb[3 * i]) + 0.7152 * double(img.rgb[3 * i + 1]) + 0.0722 * double(img.rgb[3 * i + 2]);
}

/// Compares img with an independent reference ref of the same size (both rendered with variance channels).
inline ErrorCheck compare_with_reference(const Image& img, const Image& ref) {
  ErrorCheck c;
  std::vector<double> d2;
  const size_t n = size_t(img.width) * size_t(img.height);
  for (size_t i = 0; i < n; ++i) {
    const double r = pixel_luminance(ref, i);
    const double d = pixel_luminance(img, i) - r, w = 1.0 / (r * r + 0.01);
    c.predicted += (luminance_variance(img, i) + luminance_variance(ref, i)) * w;
    d2.push_back(d * d * w);
  }
  c.n = n;
  c.measured = std::accumulate(d2.begin(), d2.end(), 0.0);
  const double mean = c.measured / double(n);
  double ss = 0;
  for (double v : d2) ss += (v - mean) * (v - mean);
  c.sd = n > 1 ? std::sqrt(ss / double(n - 1) * double(n)) : 0.0;
  return c;
}

}  // namespace tessera::testing
