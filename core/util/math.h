// Floating-point utilities shared by the geometric core: vector aliases, rounding-error bounds and ulp stepping.
#pragma once

#include <glm/glm.hpp>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace tessera {

using Vec2 = glm::vec2;
using Vec3 = glm::vec3;
using Vec3d = glm::dvec3;

inline constexpr float kInfinity = std::numeric_limits<float>::infinity();
inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;

/// Half the distance between 1 and the next float: the relative rounding error of one IEEE operation.
inline constexpr float kMachineEpsilon = std::numeric_limits<float>::epsilon() * 0.5f;

/// Higham's gamma_n = n*eps/(1-n*eps): bounds the relative error accumulated by n rounded operations.
constexpr float gamma(int n) { return (float(n) * kMachineEpsilon) / (1.0f - float(n) * kMachineEpsilon); }

/// The smallest float strictly greater than v (v itself for +inf and NaN).
inline float next_float_up(float v) {
  if (std::isinf(v) && v > 0.f) return v;
  if (v == -0.f) v = 0.f;
  uint32_t ui = std::bit_cast<uint32_t>(v);
  ui = (v >= 0.f) ? ui + 1 : ui - 1;
  return std::bit_cast<float>(ui);
}

/// The largest float strictly smaller than v (v itself for -inf and NaN).
inline float next_float_down(float v) {
  if (std::isinf(v) && v < 0.f) return v;
  if (v == 0.f) v = -0.f;
  uint32_t ui = std::bit_cast<uint32_t>(v);
  ui = (v > 0.f) ? ui - 1 : ui + 1;
  return std::bit_cast<float>(ui);
}

/// True when all three components are finite numbers.
inline bool is_finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Index of the component with the largest absolute value (the first one on ties).
inline int max_abs_dimension(const Vec3& v) {
  const Vec3 a = glm::abs(v);
  return (a.x >= a.y) ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
}

/// Largest component.
inline float max_component(const Vec3& v) { return std::max(v.x, std::max(v.y, v.z)); }

/// Squared length.
inline float length_squared(const Vec3& v) { return glm::dot(v, v); }

}  // namespace tessera
