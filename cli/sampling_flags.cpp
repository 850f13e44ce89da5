#include "cli/sampling_flags.h"

#include "core/util/enum_names.h"
#include "core/render/render.h"

namespace tessera::cli {

void add_sampling_flags(CLI::App* c, SamplingArgs& a) {
  c->add_option("--spp", a.spp, "Samples per pixel (default: the scene's)")->check(CLI::Range(1u, 1u << 20));
  c->add_option("--seed", a.seed, "Sample seed");
  c->add_option("--integrator", a.integrator, "Render with this integrator whatever the scene says")
      ->check(CLI::IsMember({"direct", "intersection_test"}));
  c->add_option("--target-error", a.target_error,
                "Sample each pixel in doubling rounds until the relative standard error of its luminance is at most "
                "this (e.g. 0.02); --spp is then ignored")
      ->check(CLI::Range(0.0, 1e6));
  c->add_option("--min-spp", a.min_spp, "With --target-error: samples of the first round")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  c->add_option("--max-spp", a.max_spp, "With --target-error: most samples per pixel")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  c->add_option("--error-floor", a.error_floor,
                "With --target-error: luminance below which absolute error is measured (default 0.01)")
      ->check(CLI::Range(0.0, 1e6));
  c->add_option("--replicates", a.replicates,
                "Split each pixel's samples into K independently scrambled sequences so the variance channels and "
                "--target-error use an unbiased error estimate (default 1: one stratified sequence, conservative "
                "estimate)")
      ->check(CLI::Range(1u, kMaxReplicates));
  c->add_option("--area-sampling", a.area_sampling, "Area-light strategy (overrides the scene)")
      ->check(CLI::IsMember(enum_names(kAreaSamplingNames)));
  c->add_option("--env-sampling", a.env_sampling, "Environment strategy (overrides the scene)")
      ->check(CLI::IsMember(enum_names(kEnvSamplingNames)));
  c->add_option("--bvh", a.bvh, "BVH build: binned SAH or object median (overrides the scene)")
      ->check(CLI::IsMember(enum_names(kSplitMethodNames)));
  c->add_option("--layers", a.layers,
                "Output layers written beside the colour, comma-separated: albedo, normal, depth, position, "
                "material_id, object_id, variance, crypto_material, crypto_object (first-hit layers describe the "
                "first surface that is not glass or refraction)")
      ->check([](const std::string& v) {
        try {
          (void)parse_layers(v);
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      });
}

protocol::SamplingSettings sampling_settings(const SamplingArgs& a, uint32_t spp) {
  protocol::SamplingSettings s;
  s.spp = spp;
  s.seed = a.seed;
  if (!a.integrator.empty()) s.integrator = "direct";
  s.target_error = a.target_error;
  s.min_spp = a.min_spp;
  s.max_spp = a.max_spp;
  s.error_floor = a.error_floor;
  s.replicates = a.replicates;
  s.area_sampling = a.area_sampling;
  s.env_sampling = a.env_sampling;
  s.bvh = a.bvh;
  s.layers = parse_layers(a.layers);
  return s;
}

}  // namespace tessera::cli
