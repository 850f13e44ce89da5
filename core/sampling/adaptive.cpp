#include "core/sampling/adaptive.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tessera {

namespace {

// Rec.709 luminance in double precision.
double luminance_d(const glm::dvec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

}  // namespace

PixelAccumulator::PixelAccumulator(uint32_t replicates) : k_(std::clamp<uint32_t>(replicates, 1, kMaxReplicates)) {}

void PixelAccumulator::add(const Vec3& L) {
  const glm::dvec3 l(L);
  sum_ += l;
  sum2_ += l * l;
  const double y = luminance_d(l);
  y_sum_ += y;
  y_sum2_ += y * y;
  if (k_ > 1) {  // one replicate's sums would equal sum_ and y_sum_, and are never read
    double* r = rep_[n_ % k_];
    r[0] += l.x;
    r[1] += l.y;
    r[2] += l.z;
    r[3] += y;
  }
  ++n_;
}

double PixelAccumulator::var_mean(double sum, double sum2, const double* rep) const {
  const double n = double(n_);
  const double mean = sum / n;
  if (k_ == 1) return n_ > 1 ? std::max(0.0, (sum2 - n * mean * mean) / (n - 1.0)) / n : 0.0;
  // Replicates need equally many samples each (rounds are multiples of k_); otherwise no estimate.
  if (n_ % k_ != 0) return 0.0;
  const double per = n / double(k_);
  double ss = 0.0;
  for (uint32_t r = 0; r < k_; ++r) {
    const double d = rep[4 * r] / per - mean;
    ss += d * d;
  }
  return ss / (double(k_) * double(k_ - 1));
}

PixelEstimate PixelAccumulator::estimate() const {
  PixelEstimate e;
  e.spp = n_;
  if (n_ == 0) return e;
  e.mean = Vec3(sum_ / double(n_));
  // Samples are finite floats, so their mean is too; the variance of the mean can exceed the float range.
  for (int c = 0; c < 3; ++c)
    e.var_mean[c] = float(std::min(var_mean(sum_[c], sum2_[c], &rep_[0][c]), double(std::numeric_limits<float>::max())));
  return e;
}

size_t PixelAccumulator::state_size(uint32_t replicates) {
  const uint32_t k = std::clamp<uint32_t>(replicates, 1, kMaxReplicates);
  return 8 + (k > 1 ? 4 * size_t(k) : 0);
}

std::vector<std::string> PixelAccumulator::state_names(uint32_t replicates) {
  std::vector<std::string> names = {"sum.R", "sum.G", "sum.B", "sum2.R", "sum2.G", "sum2.B", "sum.Y", "sum2.Y"};
  const uint32_t k = std::clamp<uint32_t>(replicates, 1, kMaxReplicates);
  if (k > 1)
    for (uint32_t r = 0; r < k; ++r)
      for (const char* c : {".R", ".G", ".B", ".Y"}) names.push_back("rep" + std::to_string(r) + c);
  return names;
}

void PixelAccumulator::save(double* out) const {
  for (int c = 0; c < 3; ++c) {
    out[c] = sum_[c];
    out[3 + c] = sum2_[c];
  }
  out[6] = y_sum_;
  out[7] = y_sum2_;
  if (k_ > 1) std::copy(&rep_[0][0], &rep_[0][0] + 4 * size_t(k_), out + 8);
}

PixelAccumulator PixelAccumulator::restore(uint32_t replicates, uint32_t count, const double* state) {
  PixelAccumulator acc(replicates);
  for (int c = 0; c < 3; ++c) {
    acc.sum_[c] = state[c];
    acc.sum2_[c] = state[3 + c];
  }
  acc.y_sum_ = state[6];
  acc.y_sum2_ = state[7];
  // With one replicate the replicate sums are never read (var_mean uses sum_ and sum2_), so they are not stored.
  if (acc.k_ > 1) std::copy(state + 8, state + 8 + 4 * size_t(acc.k_), &acc.rep_[0][0]);
  acc.n_ = count;
  return acc;
}

double PixelAccumulator::relative_error(double floor) const {
  if (n_ < 2) return std::numeric_limits<double>::infinity();
  const double n = double(n_);
  const double scale = std::max(y_sum_ / n, floor);
  const double unseen = scale / n;
  return std::sqrt(var_mean(y_sum_, y_sum2_, &rep_[0][3]) + unseen * unseen) / scale;
}

}  // namespace tessera
