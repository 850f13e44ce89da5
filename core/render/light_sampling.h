// The light-sampling strategies a scene or the command line chooses, and their names.
#pragma once

#include <string_view>

namespace tessera {

/// How area lights are sampled (the speed-against-error comparisons select each strategy by this).
enum class AreaSampling {
  /// The default. With a receiver normal (both integrators pass one): rectangles approximately in proportion to
  /// their unoccluded contribution, by projected solid angle when close (spherical rectangles warped by the cosines
  /// towards their corners, Hart et al. 2020) and by area warped by the contributions of their corners when far.
  /// Without one: per shading point, rectangles by solid angle when it is close to them, by area when far. Other
  /// triangles by area, spheres by cone in both cases.
  kAuto,
  kSolidAngle,  ///< Spherical rectangles for rectangles, uniform cones for spheres.
  kArea,        ///< Uniform points by area (the baseline).
};

/// Names of the AreaSampling values (scene key integrator.area_sampling, --area-sampling), in declaration order.
inline constexpr std::string_view kAreaSamplingNames[] = {"auto", "solid_angle", "area"};

/// How the environment is sampled at a diffuse point.
enum class EnvSampling {
  kMis,         ///< Importance sampling of the map and cosine sampling, power heuristic (default).
  kImportance,  ///< Importance sampling of the map only.
  kCosine,      ///< Cosine-weighted hemisphere only.
  kUniform,     ///< Uniform sphere directions (the baseline).
};

/// Names of the EnvSampling values (scene key integrator.env_sampling, --env-sampling), in declaration order.
inline constexpr std::string_view kEnvSamplingNames[] = {"mis", "importance", "cosine", "uniform"};

}  // namespace tessera
