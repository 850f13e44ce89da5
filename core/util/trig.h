// Trigonometric functions of floats computed by this code alone. glibc picks an FMA or a non-FMA variant of sinf and
// cosf at run time (by CPU), and the two may round a result differently; other releases of glibc (or another libm)
// compute tanf, atan2f and acosf differently (glibc 2.41 made them correctly rounded). Pixels must not depend on the CPU or
// the C library, so the renderer uses these instead: only IEEE double additions, multiplications, divisions and
// square roots, never contracted (-ffp-contract=off), each result within one float ulp of the exact value.
#pragma once

namespace tessera {

/// sin(x): within one float ulp of the exact value for |x| < 2^20 (larger arguments lose accuracy, never determinism).
float portable_sin(float x);
/// cos(x), as portable_sin.
float portable_cos(float x);

/// Sine and cosine of one angle, each bitwise equal to portable_sin(x) and portable_cos(x), from one reduction.
struct SinCos {
  float sin;  ///< portable_sin(x).
  float cos;  ///< portable_cos(x).
};
/// portable_sin(x) and portable_cos(x) together.
SinCos portable_sincos(float x);

/// tan(x): within one float ulp for |x| < 2^20, as portable_sin.
float portable_tan(float x);

/// atan2(y, x) in [-pi, pi], within one float ulp, with std::atan2's signs of zero and its special values.
float portable_atan2(float y, float x);
/// acos(x) in [0, pi] for x in [-1, 1] (NaN outside), within one float ulp.
float portable_acos(float x);

}  // namespace tessera
