// Sine and cosine of float angles computed by this code alone. glibc picks an FMA or a non-FMA variant of sinf and
// cosf at run time (by CPU), and the two may round a result differently; pixels must not depend on the CPU, so the
// sampling code uses these instead (only IEEE double additions and multiplications, never contracted: -ffp-contract=off).
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

}  // namespace tessera
