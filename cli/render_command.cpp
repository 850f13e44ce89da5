#include "cli/render_command.h"

#include "cli/progress_bar.h"
#include "cli/render_farm.h"

#include "core/enum_names.h"
#include "core/render.h"
#include "core/scene_loader.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <cstdio>
#include <memory>
#include <unistd.h>

namespace tessera::cli {

CLI::App* add_render_command(CLI::App& app, RenderArgs& a) {
  auto* c = app.add_subcommand("render", "Render a scene to an OpenEXR file on this machine");
  c->add_option("scene", a.scene, "Scene file (course JSON format)")->required()->check(CLI::ExistingFile);
  c->add_option("-o,--output", a.output, "Output EXR file")->required();
  c->add_option("--spp", a.spp, "Samples per pixel (default: the scene's)")->check(CLI::Range(1u, 1u << 20));
  c->add_option("--threads", a.threads, "Worker threads (default: all cores)")->check(CLI::Range(0, 4096));
  c->add_option("--seed", a.seed, "Sample seed");
  c->add_option("--integrator", a.integrator, "Render with this integrator whatever the scene says")
      ->check(CLI::IsMember({"direct", "intersection_test"}));
  c->add_option("--crop", a.crop, "Render only pixels [X0,X1) x [Y0,Y1) (row 0 = top)")->expected(4);
  c->add_flag("--half", a.half, "Write half floats instead of float32");
  c->add_flag("--variance", a.variance, "Also write per-pixel variance-of-the-mean and sample-count channels");
  c->add_option("--preview", a.preview, "Also write an sRGB tone-mapped PNG");
  c->add_flag("--strict", a.strict, "Treat unknown scene keys as errors");
  c->add_option("--asset-root", a.asset_root, "Allow asset paths anywhere below this folder");
  c->add_option("--tile", a.tile_size, "Tile edge in pixels for the thread scheduler")->check(CLI::Range(1, 4096));
  c->add_flag("-q,--quiet", a.quiet, "No progress bar");
  c->add_option("--workers", a.workers,
                "Render through a private coordinator and N worker processes on this machine (0: in this process)")
      ->check(CLI::Range(0, 256));
  c->add_option("--farm-tile", a.farm_tile, "Farm tile edge in pixels (with --workers)")->check(CLI::Range(1, 4096));
  c->add_option("--target-error", a.target_error,
                "Sample each pixel in doubling rounds until the relative standard error of its luminance is at most "
                "this (e.g. 0.02); --spp is then ignored")
      ->check(CLI::Range(0.f, 1e6f));
  c->add_option("--min-spp", a.min_spp, "With --target-error: samples of the first round")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  c->add_option("--max-spp", a.max_spp, "With --target-error: most samples per pixel")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  c->add_option("--error-floor", a.error_floor,
                "With --target-error: luminance below which absolute error is measured (default 0.01)")
      ->check(CLI::Range(0.f, 1e6f));
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
  return c;
}

int run_render(const RenderArgs& a) {
  // Warnings and errors go to stderr with the progress bar and the summary; stdout stays free for data.
  auto logger = spdlog::get("render");
  if (!logger) logger = spdlog::stderr_color_mt("render");
  spdlog::set_default_logger(logger);
  if (a.workers > 0) return run_render_farm(a);
  try {
    std::unique_ptr<tbb::global_control> limit;
    if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
    LoadOptions lo;
    lo.strict = a.strict;
    lo.force_direct = !a.integrator.empty();
    if (!a.asset_root.empty()) lo.asset_root = a.asset_root;
    lo.spp = a.spp;
    // Empty when not given; otherwise CLI11 has checked the name against the same table.
    lo.area_sampling = enum_from_name<AreaSampling>(a.area_sampling, kAreaSamplingNames);
    lo.env_sampling = enum_from_name<EnvSampling>(a.env_sampling, kEnvSamplingNames);
    lo.bvh = enum_from_name<SplitMethod>(a.bvh, kSplitMethodNames);
    if (a.target_error > 0.f && a.min_spp > a.max_spp) {
      spdlog::error("--min-spp {} is larger than --max-spp {}", a.min_spp, a.max_spp);
      return 2;
    }
    const auto t_load = std::chrono::steady_clock::now();
    LoadedScene loaded = load_scene_file(a.scene, lo);
    for (const auto& w : loaded.warnings) spdlog::warn("{}", w);
    for (const auto& n : loaded.notes) spdlog::info("{}", n);
    const Scene& scene = loaded.scene;
    const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count();

    RenderOptions ro;
    ro.seed = a.seed;
    ro.tile_size = a.tile_size;
    ro.variance = a.variance;
    ro.target_error = a.target_error;
    ro.min_spp = a.min_spp;
    ro.max_spp = a.max_spp;
    ro.error_floor = a.error_floor;
    ro.replicates = a.replicates;
    if (a.replicates > 1 && ro.target_error <= 0.f && (a.spp ? *a.spp : scene.settings.spp) % a.replicates != 0)
      spdlog::warn("--replicates {} does not divide the sample count; the variance channels will be zero",
                   a.replicates);
    if (!a.crop.empty()) {
      ro.window = PixelWindow{a.crop[0], a.crop[1], a.crop[2], a.crop[3]};
      const PixelWindow full{0, 0, scene.width, scene.height};
      if (ro.window.empty() || !full.contains(ro.window)) {
        spdlog::error("--crop {} {} {} {} is empty or outside the {}x{} image", a.crop[0], a.crop[1], a.crop[2],
                      a.crop[3], scene.width, scene.height);
        return 2;
      }
    }
    ProgressBar bar(!a.quiet);
    ro.progress = [&](const RenderProgress& p) { bar.update(p); };
    const RenderResult res = render(scene, ro);

    ExrWriteOptions wo;
    wo.half = a.half;
    wo.data_window = res.window;
    wo.display_window = PixelWindow{0, 0, scene.width, scene.height};
    wo.metadata = {{"tessera:version", TESSERA_VERSION},
                   {"tessera:scene", a.scene},
                   {"tessera:sceneHash", scene.hash},
                   {"tessera:spp", ro.target_error > 0.f ? std::string("adaptive")
                                                         : std::to_string(a.spp ? *a.spp : scene.settings.spp)},
                   {"tessera:seed", std::to_string(a.seed)},
                   {"tessera:renderSeconds", std::to_string(res.seconds)}};
    if (ro.target_error > 0.f) {
      wo.metadata["tessera:targetError"] = std::to_string(ro.target_error);
      wo.metadata["tessera:minSpp"] = std::to_string(ro.min_spp);
      wo.metadata["tessera:maxSpp"] = std::to_string(ro.max_spp);
      wo.metadata["tessera:errorFloor"] = std::to_string(ro.error_floor);
    }
    wo.metadata["tessera:replicates"] = std::to_string(ro.replicates);
    wo.metadata["tessera:areaSampling"] = std::string(enum_name(scene.settings.area_sampling, kAreaSamplingNames));
    wo.metadata["tessera:envSampling"] = std::string(enum_name(scene.settings.env_sampling, kEnvSamplingNames));
    write_exr(a.output, res.image, wo);
    if (!a.preview.empty()) write_png_srgb(a.preview, res.image);
    if (res.counters.nonfinite > 0)
      spdlog::warn("{} sample(s) were NaN or Inf and were counted as zero", res.counters.nonfinite);
    const double pixels = double(res.window.width()) * double(res.window.height());
    const double mean_spp = pixels > 0 ? double(res.counters.camera) / pixels : 0.0;
    if (ro.target_error > 0.f)
      std::fprintf(stderr, "adaptive: target relative error %g, %u..%u spp, %.1f spp on average\n", ro.target_error,
                   ro.min_spp, ro.max_spp, mean_spp);
    char spp_text[32];
    if (ro.target_error > 0.f) std::snprintf(spp_text, sizeof spp_text, "%.1f", mean_spp);
    else std::snprintf(spp_text, sizeof spp_text, "%u", a.spp ? *a.spp : scene.settings.spp);
    std::fprintf(stderr, "%s: %dx%d px, %s spp (%llu samples), %.2fs load + %.2fs render, %.1f Mrays/s (%llu rays)\n",
                 a.output.c_str(), res.window.width(), res.window.height(), spp_text,
                 static_cast<unsigned long long>(res.counters.camera), load_s, res.seconds,
                 res.seconds > 0 ? double(res.counters.rays) / res.seconds * 1e-6 : 0.0,
                 static_cast<unsigned long long>(res.counters.rays));
    return 0;
  } catch (const SceneError& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("render failed: {}", e.what());
    return 1;
  }
}

}  // namespace tessera::cli
