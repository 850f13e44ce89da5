// Test-only: comparing a render's measured error against an independent reference with the error the renders
// predict for themselves (their variance-of-the-mean channels), with a tolerance estimated from the data.
#pragma once

#include "core/image/image.h"

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
  /// Sum of the luminance differences D over its predicted standard deviation sqrt(sum (Var(I) + Var(R))): about
  /// N(0, 1) when neither image is biased, and far from 0 when one is biased the same way over many pixels (which
  /// the sum of D^2 notices only once the bias is comparable with the noise).
  double bias_z = 0;
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
  double sum_d = 0, sum_v = 0;
  const size_t n = size_t(img.width) * size_t(img.height);
  for (size_t i = 0; i < n; ++i) {
    const double r = pixel_luminance(ref, i);
    const double d = pixel_luminance(img, i) - r, w = 1.0 / (r * r + 0.01);
    const double v = luminance_variance(img, i) + luminance_variance(ref, i);
    c.predicted += v * w;
    d2.push_back(d * d * w);
    sum_d += d;
    sum_v += v;
  }
  c.bias_z = sum_v > 0 ? sum_d / std::sqrt(sum_v) : 0.0;
  c.n = n;
  c.measured = std::accumulate(d2.begin(), d2.end(), 0.0);
  const double mean = c.measured / double(n);
  double ss = 0;
  for (double v : d2) ss += (v - mean) * (v - mean);
  c.sd = n > 1 ? std::sqrt(ss / double(n - 1) * double(n)) : 0.0;
  return c;
}

/// P(|T| > t) for Student's t distribution with nu degrees of freedom (nu >= 1, t > 0): the density integrated from t
/// to infinity by Simpson's rule in u = t / x (the integrand u^(nu-1)-like near u = 0, smooth on (0, 1]), doubled.
inline double student_t_two_sided_tail(double t, double nu) {
  const double c = std::exp(std::lgamma((nu + 1) / 2) - std::lgamma(nu / 2)) / std::sqrt(nu * M_PI);
  auto g = [&](double u) {  // density at x = t / u times dx/du = t / u^2
    if (u <= 0) return 0.0;
    const double x = t / u;
    return c * std::pow(1 + x * x / nu, -(nu + 1) / 2) * t / (u * u);
  };
  const int steps = 2000;  // even
  const double h = 1.0 / steps;
  double sum = g(0) + g(1);
  for (int i = 1; i < steps; ++i) sum += (i % 2 ? 4 : 2) * g(i * h);
  return 2 * sum * h / 3;
}

/// The smallest m with P(X > m) <= alpha for X ~ Poisson(lambda): a bound on a count of rare independent events
/// whose expected number is lambda (the Poisson law bounds the tail of a sum of independent Bernoulli variables
/// with small probabilities and the same mean well).
inline size_t poisson_upper_bound(double lambda, double alpha) {
  double p = std::exp(-lambda), cdf = p;
  size_t m = 0;
  while (1 - cdf > alpha) {
    ++m;
    p *= lambda / double(m);
    cdf += p;
  }
  return m;
}

}  // namespace tessera::testing
