#include "core/adaptive.h"

#include <algorithm>
#include <cmath>

namespace tessera {

namespace {

// Rec.709 luminance in double precision.
double luminance_d(const glm::dvec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

}  // namespace

void PixelAccumulator::add(const Vec3& L) {
  const glm::dvec3 l(L);
  sum_ += l;
  sum2_ += l * l;
  const double y = luminance_d(l);
  y_sum_ += y;
  y_sum2_ += y * y;
  ++n_;
}

PixelEstimate PixelAccumulator::estimate() const {
  PixelEstimate e;
  e.spp = n_;
  if (n_ == 0) return e;
  const double n = double(n_);
  const glm::dvec3 mean = sum_ / n;
  e.mean = Vec3(mean);
  if (n_ > 1) e.var_mean = Vec3(glm::max(glm::dvec3(0.0), (sum2_ - n * mean * mean) / (n - 1.0)) / n);
  return e;
}

double PixelAccumulator::relative_error(double floor) const {
  if (n_ < 2) return 0.0;
  const double n = double(n_);
  const double mean = y_sum_ / n;
  const double var_mean = std::max(0.0, (y_sum2_ - n * mean * mean) / (n - 1.0)) / n;
  return std::sqrt(var_mean) / std::max(mean, floor);
}

}  // namespace tessera
