#include "core/trig.h"

#include <cmath>
#include <cstdint>

namespace tessera {
namespace {

// pi/2 split so that k * kPio2Hi is exact for |k| < 2^20 (kPio2Hi has 33 significant bits), and the rest.
constexpr double kPio2Hi = 1.57079632673412561417e+00;
constexpr double kPio2Lo = 6.07710050650619224932e-11;
constexpr double kTwoOverPi = 0.63661977236758134308;

// Taylor polynomials on |r| <= pi/4 (+ a little): truncation below 1e-11 relative, far under a float ulp (6e-8).
double sin_poly(double r) {
  const double r2 = r * r;
  return r + r * r2 * (-1.0 / 6 + r2 * (1.0 / 120 + r2 * (-1.0 / 5040 + r2 * (1.0 / 362880 + r2 * (-1.0 / 39916800)))));
}
double cos_poly(double r) {
  const double r2 = r * r;
  return 1.0 + r2 * (-1.0 / 2 + r2 * (1.0 / 24 + r2 * (-1.0 / 720 + r2 * (1.0 / 40320 + r2 * (-1.0 / 3628800 +
                                                                                          r2 * (1.0 / 479001600))))));
}

// floor(v), exactly as std::floor (which is exact in every libm variant), without a library call for |v| < 2^52:
// truncation to an integer is exact there, and one below it when it rounded a negative value up. The argument is
// never -0 here (x * 2/pi + 0.5 is not), the only value whose floor's sign this would lose.
double floor_exact(double v) {
  if (!(std::abs(v) < 4503599627370496.0)) return std::floor(v);  // already an integer, infinite or NaN
  const double t = double(int64_t(v));
  return t > v ? t - 1.0 : t;
}

// x = k pi/2 + r with |r| <= pi/4; the quadrant is k mod 4.
double reduce(float x, int* quadrant) {
  const double xd = double(x);
  const double k = floor_exact(xd * kTwoOverPi + 0.5);
  // k mod 4; a double of magnitude 2^63 or more is a multiple of 4 (and would not convert to int64_t).
  *quadrant = std::abs(k) < 9223372036854775808.0 ? int(int64_t(k) & 3) : 0;
  return (xd - k * kPio2Hi) - k * kPio2Lo;
}

}  // namespace

float portable_sin(float x) {
  int q;
  const double r = reduce(x, &q);
  switch (q) {
    case 0: return float(sin_poly(r));
    case 1: return float(cos_poly(r));
    case 2: return float(-sin_poly(r));
    default: return float(-cos_poly(r));
  }
}

float portable_cos(float x) {
  int q;
  const double r = reduce(x, &q);
  switch (q) {
    case 0: return float(cos_poly(r));
    case 1: return float(-sin_poly(r));
    case 2: return float(-cos_poly(r));
    default: return float(sin_poly(r));
  }
}

SinCos portable_sincos(float x) {
  int q;
  const double r = reduce(x, &q);
  const double s = sin_poly(r), c = cos_poly(r);
  switch (q) {
    case 0: return {float(s), float(c)};
    case 1: return {float(c), float(-s)};
    case 2: return {float(-s), float(-c)};
    default: return {float(-c), float(s)};
  }
}

}  // namespace tessera
