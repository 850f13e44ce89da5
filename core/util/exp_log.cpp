#include "core/util/exp_log.h"

#include <cmath>
#include <cstdint>
#include <limits>

namespace tessera {
namespace {

// ln 2 split so that k * kLn2Hi is exact for |k| < 2^20 (kLn2Hi has 32 significant bits), and the rest.
constexpr double kLn2Hi = 6.93147180369123816490e-01;
constexpr double kLn2Lo = 1.90821492927058770002e-10;
constexpr double kInvLn2 = 1.44269504088896338700e+00;
constexpr double kTwoOverSqrtPi = 1.1283791670955126;
constexpr double kInvSqrtPi = 0.5641895835477563;

// round(v) for |v| < 2^31, as an exact double: truncation and one step.
double round_exact(double v) {
  const double t = double(int64_t(v));
  const double f = v - t;  // exact
  return f >= 0.5 ? t + 1.0 : (f < -0.5 ? t - 1.0 : t);
}

// log(m) for m in [sqrt(1/2), sqrt(2)]: 2 atanh(s) with s = (m - 1)/(m + 1), |s| <= 0.172, to s^25 (1e-20 relative).
double log_near_one(double m) {
  const double s = (m - 1.0) / (m + 1.0), s2 = s * s;
  double p = 1.0 / 25;
  for (int k = 23; k >= 1; k -= 2) p = 1.0 / k + s2 * p;
  return 2.0 * s * p;
}

// log(u) for a finite u > 0: u = m 2^e with m in [sqrt(1/2), sqrt(2)).
double log_positive(double u) {
  int e;
  double m = std::frexp(u, &e);  // exact: m in [1/2, 1)
  if (m < 0.70710678118654752) {
    m *= 2.0;
    --e;
  }
  return (double(e) * kLn2Hi + log_near_one(m)) + double(e) * kLn2Lo;
}

}  // namespace

double portable_exp(double x) {
  if (std::isnan(x)) return x;
  if (x > 709.782712893384) return std::numeric_limits<double>::infinity();
  if (x < -745.2) return 0.0;
  // x = k ln2 + r, |r| <= ln2/2 (a little more through rounding); e^r from its Taylor series to r^13 (4e-18).
  const double k = round_exact(x * kInvLn2);
  const double r = (x - k * kLn2Hi) - k * kLn2Lo;
  // e^r = 1 + r (1 + r/2 (1 + r/3 (... (1 + r/13)))).
  double q = 1.0;
  for (int n = 13; n >= 2; --n) q = 1.0 + r * q * (1.0 / double(n));
  return std::ldexp(1.0 + r * q, int(k));
}

double portable_log1p(double x) {
  if (std::isnan(x) || x < -1.0) return std::numeric_limits<double>::quiet_NaN();
  if (x == -1.0) return -std::numeric_limits<double>::infinity();
  if (std::isinf(x)) return x;
  const double u = 1.0 + x;
  if (u == 1.0) return x;  // |x| below half a double ulp of 1: log1p(x) = x to double precision
  // log(u) corrected by x / (u - 1) for the rounding of 1 + x (Goldberg's trick): relative error about 2 ulps.
  return log_positive(u) * (x / (u - 1.0));
}

double portable_erf(double x) {
  if (std::isnan(x)) return x;
  const double a = std::abs(x);
  double r;
  if (a >= 6.0) {
    r = 1.0;
  } else if (a < 3.0) {
    // erf(a) = 2/sqrt(pi) e^{-a^2} sum_n 2^n a^(2n+1) / (1 3 5 ... (2n+1)): positive terms, no cancellation.
    double t = a, s = a;
    for (int n = 1; n < 80 && t >= 1e-17 * s; ++n) {
      t *= 2.0 * a * a / double(2 * n + 1);
      s += t;
    }
    r = kTwoOverSqrtPi * portable_exp(-a * a) * s;
  } else {
    // erfc(a) = e^{-a^2}/sqrt(pi) / (a + (1/2)/(a + 1/(a + (3/2)/(a + ...)))), 30 levels (4e-15 relative for a >= 3).
    double f = a;
    for (int k = 30; k >= 1; --k) f = a + (0.5 * double(k)) / f;
    r = 1.0 - kInvSqrtPi * portable_exp(-a * a) / f;
  }
  return x < 0.0 ? -r : r;
}

}  // namespace tessera
