#include "core/util/trig.h"

#include <cmath>
#include <cstdint>
#include <limits>

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

// atan(k / 16) for k = 0..16.
constexpr double kAtanTable[17] = {
    0.0,
    0.06241880999595735,
    0.12435499454676144,
    0.18534794999569476,
    0.24497866312686414,
    0.3028848683749714,
    0.35877067027057225,
    0.4124104415973873,
    0.4636476090008061,
    0.5123894603107377,
    0.5585993153435624,
    0.6022873461349642,
    0.6435011087932844,
    0.6823165548747481,
    0.7188299996216245,
    0.7531512809621944,
    0.7853981633974483,
};
// In double, and named apart from math.h's float kPi, which the arithmetic here must never pick up.
constexpr double kPiD = 3.141592653589793;
constexpr double kHalfPiD = 1.5707963267948966;

// atan(a) for a in [0, 1]: atan(c) + atan((a - c) / (1 + a c)) with c = k/16 the nearest table point, so the
// reduced argument is at most 1/32 and its series (to t^9) is exact to 1e-17 relative.
double atan_unit(double a) {
  const int k = int(a * 16.0 + 0.5);
  const double c = double(k) * 0.0625;
  const double t = (a - c) / (1.0 + a * c);
  const double t2 = t * t;
  return kAtanTable[k] + (t + t * t2 * (-1.0 / 3 + t2 * (1.0 / 5 + t2 * (-1.0 / 7 + t2 * (1.0 / 9)))));
}

// atan2(y, x) of finite doubles with y >= 0 (y = x = 0 included: 0 or pi by x's sign, as std::atan2).
double atan2_nonneg_y(double y, double x) {
  const double ax = std::abs(x);
  double r;
  if (y == 0.0) r = 0.0;
  else if (y <= ax) r = atan_unit(y / ax);
  else r = kHalfPiD - atan_unit(ax / y);
  return std::signbit(x) ? kPiD - r : r;
}

}  // namespace

float portable_atan2(float y, float x) {
  if (std::isnan(x) || std::isnan(y)) return x + y;
  double r;
  if (std::isinf(y)) r = std::isinf(x) ? (x > 0 ? kPiD / 4 : 3 * kPiD / 4) : kHalfPiD;  // C's values at infinity
  else if (std::isinf(x)) r = x > 0 ? 0.0 : kPiD;
  else r = atan2_nonneg_y(std::abs(double(y)), double(x));
  return float(std::signbit(y) ? -r : r);
}

float portable_acos(float x) {
  if (!(x >= -1.f && x <= 1.f)) return std::numeric_limits<float>::quiet_NaN();
  const double xd = double(x);
  // sin = sqrt((1 - x)(1 + x)): both factors exact for a float x.
  return float(atan2_nonneg_y(std::sqrt((1.0 - xd) * (1.0 + xd)), xd));
}

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

float portable_tan(float x) {
  int q;
  const double r = reduce(x, &q);
  // tan(r + k pi/2) = tan(r) for even k, -cot(r) for odd k: one rounding of the double quotient.
  return float(q % 2 == 0 ? sin_poly(r) / cos_poly(r) : -cos_poly(r) / sin_poly(r));
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
