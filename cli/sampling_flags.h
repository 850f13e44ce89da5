// The sampling options `tessera render` and `tessera submit` share: registered on both commands by one function and
// turned into a job's protocol::SamplingSettings by another, so a farm job is sampled as the same render on one
// machine would be.
#pragma once

#include "core/sampling/adaptive.h"
#include "protocol/messages.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace tessera::cli {

/// How to sample a scene, as given on the command line.
/// The adaptive settings are kept as the job's settings hold them (double); a render on this machine and a farm job
/// both make their float thresholds from those (protocol::SamplingSettings::apply_to), so the two cannot differ.
struct SamplingArgs {
  std::optional<uint32_t> spp;                   ///< Samples per pixel override.
  uint64_t seed = 0;                             ///< Sample seed.
  std::string integrator;                        ///< "direct" renders scenes of other integrator types.
  double target_error = 0.0;                     ///< Adaptive sampling target (relative standard error); 0: off.
  uint32_t min_spp = kAdaptiveMinSpp;            ///< Adaptive sampling: first round and minimum.
  uint32_t max_spp = kAdaptiveMaxSpp;            ///< Adaptive sampling: cap.
  double error_floor = AdaptiveOptions{}.error_floor;  ///< Adaptive sampling: luminance floor of the relative error.
  uint32_t replicates = 1;                       ///< Independent replicates per pixel (unbiased error estimates when >= 2).
  std::string area_sampling;                     ///< Overrides integrator.area_sampling (auto, solid_angle or area).
  std::string env_sampling;                      ///< Overrides integrator.env_sampling (mis, importance, cosine, uniform).
  std::string bvh;                               ///< Overrides integrator.bvh (sah or median).
  std::string layers;                            ///< Output layers, comma-separated (core/render/layers.h).
};

/// Registers --spp, --seed, --integrator, --target-error, --min-spp, --max-spp, --error-floor, --replicates,
/// --area-sampling, --env-sampling, --bvh and --layers on `command`, writing into `args`.
void add_sampling_flags(CLI::App* command, SamplingArgs& args);

/// The settings `args` give, at `spp` samples per pixel (0: the scene's): what a render's options, the EXR metadata
/// that lets --resume repeat it exactly, and a farm job are made from.
protocol::SamplingSettings sampling_settings(const SamplingArgs& args, uint32_t spp);

}  // namespace tessera::cli
