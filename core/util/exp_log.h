// Exponential, logarithm and error function computed by this code alone, for the same reason as core/util/trig.h: glibc
// picks an FMA or a plain variant of exp and expf by CPU, and other releases of the C library compute these (and
// log1pf, erf) differently, while pixels must not depend on the machine. Only IEEE double additions, multiplications,
// divisions and exact scalings by powers of two, never contracted (-ffp-contract=off).
#pragma once

namespace tessera {

/// e^x, within 1e-15 relative for every finite x (0 below -745, infinity above 709.78, NaN for NaN).
double portable_exp(double x);
/// log(1 + x) for x > -1, within 1e-15 relative (-infinity at -1, NaN below -1 and for NaN).
double portable_log1p(double x);
/// erf(x), within 1e-14 relative for every x (odd; +-1 beyond |x| = 6, where 1 - erf is below a double ulp of 1).
double portable_erf(double x);

}  // namespace tessera
