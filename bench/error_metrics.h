// The error metrics of the speed-against-error reports (bench/speed_vs_error.cpp, bench/error_estimators.cpp):
// relMSE, RMSE and the 99th-percentile pixel error of an image against a reference.
#pragma once

#include "core/image/image.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace tessera {

struct Metrics {
  double rel_mse = 0;  // mean over pixels and channels of (I - R)^2 / (R^2 + 0.01)
  double rmse = 0;     // sqrt of mean (I - R)^2
  double p99 = 0;      // 99th percentile over pixels of sqrt(mean over channels of (I - R)^2 / (R^2 + 0.01))
};

inline Metrics metrics(const Image& img, const Image& ref) {
  Metrics m;
  const size_t n = size_t(img.width) * size_t(img.height);
  std::vector<double> per(n);
  double se = 0, rse = 0;
  for (size_t i = 0; i < n; ++i) {
    double pr = 0;
    for (int c = 0; c < 3; ++c) {
      const double r = ref.rgb[3 * i + size_t(c)], d = double(img.rgb[3 * i + size_t(c)]) - r;
      se += d * d;
      pr += d * d / (r * r + 0.01);
    }
    rse += pr;
    per[i] = std::sqrt(pr / 3);
  }
  m.rel_mse = rse / (3.0 * double(n));
  m.rmse = std::sqrt(se / (3.0 * double(n)));
  std::nth_element(per.begin(), per.begin() + ptrdiff_t(0.99 * double(n - 1)), per.end());
  m.p99 = per[size_t(0.99 * double(n - 1))];
  return m;
}

}  // namespace tessera
