// Test-only: Pearson's chi-square goodness-of-fit test of sampled directions against a density, as pbrt and Mitsuba
// test their BSDFs. Directions live on a chart (x, y) in [0,1)^2 with a known Jacobian; the test integrates the
// density over each cell of a grid on the chart, bins the samples, pools cells with small expected counts and
// returns the p-value of the observed counts.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace tessera::testing {

/// Regularised upper incomplete gamma function Q(a, x) (series below a + 1, continued fraction above).
inline double gamma_q(double a, double x) {
  if (x <= 0.0) return 1.0;
  const double lg = std::lgamma(a);
  if (x < a + 1.0) {
    double sum = 1.0 / a, term = sum;
    for (int n = 1; n < 10000; ++n) {
      term *= x / (a + n);
      sum += term;
      if (std::abs(term) < std::abs(sum) * 1e-15) break;
    }
    return 1.0 - sum * std::exp(-x + a * std::log(x) - lg);
  }
  // Lentz's method for the continued fraction of Q.
  const double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::abs(del - 1.0) < 1e-15) break;
  }
  return std::exp(-x + a * std::log(x) - lg) * h;
}

/// A chart of (part of) the sphere of directions: to_dir maps (x, y) in [0,1)^2 to a direction and the Jacobian
/// |d omega / dx dy| (nothing where the chart has no direction); from_dir maps a direction back.
struct DirectionChart {
  std::function<std::optional<std::pair<glm::dvec3, double>>(double x, double y)> to_dir;
  std::function<std::optional<glm::dvec2>(const glm::dvec3& w)> from_dir;
};

/// Result of one chi-square test.
struct ChiSquareResult {
  double p_value = 1.0;    ///< Probability of a statistic this large if the samples follow the density.
  std::string message;     ///< Empty, or what failed outright (samples where the density is zero).
  double statistic = 0.0;  ///< The chi-square statistic.
  int dof = 0;             ///< Its degrees of freedom.
};

/// Tests `n` draws of `sample` (nothing = absorbed) against `pdf` over an nx x ny grid on `chart`, integrating
/// the density with sub x sub midpoints per cell (8 times finer in cells the density's support cuts). Absorbed draws form one more cell (expected: n x the mass the
/// density misses). Every sample must have a positive density.
inline ChiSquareResult chi_square_test(const DirectionChart& chart, const std::function<double(const glm::dvec3&)>& pdf,
                                       const std::function<std::optional<glm::dvec3>()>& sample, int n, int nx, int ny,
                                       int sub = 12) {
  std::vector<double> expected(size_t(nx * ny) + 1, 0.0), observed(size_t(nx * ny) + 1, 0.0);
  double mass = 0.0;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      // Midpoints of a k x k sub-grid; counts how many were zero, to refine cells the density's support cuts.
      auto integrate = [&](int k, int* zeros) {
        double sum = 0.0;
        for (int b = 0; b < k; ++b)
          for (int a = 0; a < k; ++a) {
            const double x = (i + (a + 0.5) / k) / nx, y = (j + (b + 0.5) / k) / ny;
            const auto d = chart.to_dir(x, y);
            const double v = d ? pdf(d->first) * d->second : 0.0;
            if (!(v > 0.0)) ++*zeros;
            sum += v;
          }
        return sum / (double(k) * k * nx * ny);
      };
      int zeros = 0;
      double p = integrate(sub, &zeros);
      if (zeros > 0 && zeros < sub * sub) p = integrate(sub * 8, &zeros);
      expected[size_t(j * nx + i)] = p * n;
      mass += p;
    }
  expected.back() = std::max(0.0, 1.0 - mass) * n;
  ChiSquareResult res;
  for (int k = 0; k < n; ++k) {
    const auto w = sample();
    if (!w) {
      observed.back() += 1.0;
      continue;
    }
    if (!(pdf(*w) > 0.0)) {
      res.message = "a sample where the density is zero";
      return res;
    }
    const auto c = chart.from_dir(*w);
    if (!c) {
      res.message = "a sample fell outside the chart";
      return res;
    }
    const int i = std::clamp(int(c->x * nx), 0, nx - 1), j = std::clamp(int(c->y * ny), 0, ny - 1);
    observed[size_t(j * nx + i)] += 1.0;
  }
  // Cells are pooled in order of expected count until each pool expects at least 5.
  std::vector<size_t> order(expected.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  double stat = 0.0, pool_e = 0.0, pool_o = 0.0;
  int dof = -1;
  for (size_t k : order) {
    pool_e += expected[k];
    pool_o += observed[k];
    if (pool_e >= 5.0) {
      stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
      ++dof;
      pool_e = pool_o = 0.0;
    }
  }
  if (pool_e > 0.0) {
    stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
    ++dof;
  }
  res.statistic = stat;
  res.dof = dof;
  res.p_value = dof > 0 ? gamma_q(0.5 * dof, 0.5 * stat) : 1.0;
  return res;
}

}  // namespace tessera::testing
