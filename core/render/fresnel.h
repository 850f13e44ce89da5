// Fresnel reflectance of smooth interfaces: dielectric (unpolarised, real indices) and conductor (complex index
// eta + i k, per RGB channel).
#pragma once

#include "core/util/math.h"

namespace tessera {

/// Unpolarised reflectance of a dielectric interface. cos_i is the cosine between the incident direction and the
/// normal that points to the outside; eta = n_inside / n_outside. A negative cos_i means the light arrives from
/// the inside. Returns 1 under total internal reflection.
float fresnel_dielectric(float cos_i, float eta);

/// Unpolarised reflectance of a conductor of relative complex index eta + i k (metal over outside medium), for
/// |cos_i| (the side does not matter: light never enters a conductor). Per channel.
Vec3 fresnel_conductor(float cos_i, const Vec3& eta, const Vec3& k);

}  // namespace tessera
