#include "cli/render_command.h"

#include "cli/frame_list.h"
#include "cli/render_sequence.h"

#include "cli/asset_limit_flags.h"
#include "cli/exit_status.h"
#include "cli/interrupt_guard.h"
#include "cli/output_check.h"
#include "cli/progress_bar.h"
#include "cli/render_farm.h"
#include "cli/render_resume.h"
#include "cli/render_sequence.h"

#include "core/util/enum_names.h"
#include "core/image/exr_multipart.h"
#include "core/image/exr_stream.h"
#include "core/render/layer_film.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <system_error>
#include <thread>
#include <unistd.h>

namespace tessera::cli {

CLI::App* add_render_command(CLI::App& app, RenderArgs& a) {
  auto* c = app.add_subcommand("render", "Render a scene, or a sequence of frames, to OpenEXR files on this machine");
  add_sequence_flags(c, a.scenes, a.frames, a.frame_order, "With --workers: ");
  c->add_option("-o,--output", a.output,
                "Output EXR file; with several frames a pattern whose last run of '#' becomes the frame number "
                "(e.g. out/frame_####.exr)")
      ->required();
  add_sampling_flags(c, a);
  c->add_option("--threads", a.threads, "Worker threads (default: all cores)")->check(CLI::Range(0, 4096));
  c->add_option("--crop", a.crop, "Render only pixels [X0,X1) x [Y0,Y1) (row 0 = top)")->expected(4);
  c->add_flag("--half", a.half, "Write half floats instead of float32");
  c->add_flag("--variance", a.variance, "Also write per-pixel variance-of-the-mean and sample-count channels");
  c->add_flag("--multipart", a.multipart,
              "Write a multi-part EXR: the colour in part \"rgba\", each output layer in a part of its own name "
              "(default: one part holding every channel)");
  c->add_option("--preview", a.preview,
                "Also write an sRGB tone-mapped PNG (with several frames, a '#' pattern like -o)");
  c->add_flag("--strict", a.strict, "Treat unknown scene keys as errors");
  c->add_option("--asset-root", a.asset_root, "Allow asset paths anywhere below this folder");
  add_asset_limit_flags(c, a.asset_limits);
  c->add_option("--tile", a.tile_size, "Tile edge in pixels for the thread scheduler")->check(CLI::Range(1, 4096));
  c->add_flag("-q,--quiet", a.quiet, "No progress bar");
  c->add_flag("--timing", a.timing,
              "Print where the wall time went: load (with the BVH build), the set-up around the threaded render, the "
              "threaded render and its idle thread time, the write");
  c->add_option("--workers", a.workers,
                "Render through a private coordinator and N worker processes on this machine (0: in this process)")
      ->check(CLI::Range(0, 256));
  c->add_option("--farm-tile", a.farm_tile, "Farm tile edge in pixels (with --workers)")->check(CLI::Range(1, 4096));
  c->add_flag("--resumable", a.resumable,
              "Also write each pixel's exact sample sums, so that --resume --spp can refine the render later");
  c->add_option("--tile-budget", a.tile_budget,
                "Render at most N tiles, then write a partial EXR that --resume finishes (exit code 3)")
      ->check(CLI::Range(1, 1 << 30));
  auto* resume = c->add_option("--resume", a.resume,
                               "Finish the partial EXR FILE (written by an interrupted render or --tile-budget), or "
                               "refine a --resumable one to --spp; the sampling settings are taken from FILE. With "
                               "several frames, a '#' pattern (usually -o's): partial frames are finished, complete "
                               "ones skipped, the others rendered, all with the settings their files record")
                     ->check(file_or_pattern());
  c->add_flag("--skip-existing", a.skip_existing,
              "Skip each frame whose output is already a complete render of its scene with these settings (as the "
              "EXR's metadata records them); render the others again");
  // The sampling settings come from the file: giving them again could only contradict it.
  for (const char* name : {"--seed", "--crop", "--variance", "--layers", "--target-error", "--min-spp", "--max-spp",
                           "--error-floor", "--replicates", "--area-sampling", "--env-sampling", "--bvh", "--workers"})
    resume->excludes(c->get_option(name));
  return c;
}

namespace {

// The previous render --resume continues, checked against the scene.
StoredRender load_previous(const ExrImage& file, const RenderArgs& a, const Scene& scene) {
  const auto it = file.metadata.find("tessera:sceneHash");
  if (it == file.metadata.end() || it->second != scene.hash)
    throw Refusal(a.resume + " was rendered from another scene (or other assets) than " + a.scene);
  if (file.display_window != PixelWindow{0, 0, scene.width, scene.height})
    throw Refusal(a.resume + " is not a " + std::to_string(scene.width) + "x" + std::to_string(scene.height) +
                  " picture");
  StoredRender prev;
  try {
    prev = StoredRender{file.pixels, read_state_channels(file.pixels, a.replicates)};
  } catch (const ImageError& e) {
    throw Refusal(a.resume + ": " + e.what() + "; only partial renders and --resumable ones can be resumed");
  }
  const uint32_t stored = recorded_spp(file);
  if (a.target_error <= 0.f && *a.spp != stored && !prev.state.exact())
    throw Refusal(a.resume + " holds no exact sample sums (render with --resumable to refine later): it "
                           "can only be finished at its own " + std::to_string(stored) + " spp");
  if (a.resumable && !prev.state.exact())
    throw Refusal(a.resume + " holds no exact sample sums, so its continuation cannot be --resumable");
  return prev;
}

// Errors go to stderr with the progress bar and the summary; stdout stays free for data.
void use_render_logger() {
  auto logger = spdlog::get("render");
  if (!logger) logger = spdlog::stderr_color_mt("render");
  spdlog::set_default_logger(logger);
}

// Pixels that have samples.
size_t rendered_pixels(const RenderState& state) {
  size_t n = 0;
  for (const uint32_t s : state.samples) n += s > 0 ? 1 : 0;
  return n;
}

}  // namespace

LoadOptions scene_load_options(const RenderArgs& a) {
  LoadOptions lo;
  lo.strict = a.strict;
  lo.force_direct = !a.integrator.empty();
  if (!a.asset_root.empty()) lo.asset_root = a.asset_root;
  lo.asset_limits = a.asset_limits;
  lo.spp = a.spp;
  // Empty when not given; otherwise CLI11 has checked the name against the same table.
  lo.area_sampling = enum_from_name<AreaSampling>(a.area_sampling, kAreaSamplingNames);
  lo.env_sampling = enum_from_name<EnvSampling>(a.env_sampling, kEnvSamplingNames);
  lo.bvh = enum_from_name<SplitMethod>(a.bvh, kSplitMethodNames);
  return lo;
}

int run_render(const RenderArgs& given) {
  use_render_logger();
  if (given.scenes.empty()) return render_scene(given);
  // One scene file: one render. A pattern or glob that names no file goes to the sequence, which says so.
  std::error_code ec;
  if (given.scenes.size() == 1 && given.frames.empty() && !given.skip_existing &&
      std::filesystem::exists(given.scenes.front(), ec)) {
    RenderArgs a = given;
    a.scene = given.scenes.front();
    return render_scene(a);
  }
  return run_render_sequence(given);
}

int render_scene(const RenderArgs& given) {
  use_render_logger();
  // Before anything long: an output that cannot be written is reported now, not after the render.
  if (!output_writable(given.output) || (!given.preview.empty() && !output_writable(given.preview, "preview")))
    return kExitRefused;
  if (given.workers > 0) {
    if (given.tile_budget > 0) {
      spdlog::error("--workers renders whole jobs: drop --tile-budget");
      return kExitRefused;
    }
    return run_render_farm(given);
  }
  try {
    // This process renders here and speaks no TLS: OpenSSL serves the scene's hash only.
    start_openssl_for_digests_only();
    std::optional<ExrImage> resume_file;
    if (!given.resume.empty()) {
      try {
        resume_file = read_exr_all_parts(given.resume);
      } catch (const std::exception& e) {
        throw Refusal(e.what());
      }
    }
    const RenderArgs a = resume_file ? resumed_args(given, *resume_file) : given;
    std::unique_ptr<tbb::global_control> limit;
    if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
    const LoadOptions lo = scene_load_options(a);
    if (a.target_error > 0.f && a.min_spp > a.max_spp) {
      spdlog::error("--min-spp {} is larger than --max-spp {}", a.min_spp, a.max_spp);
      return kExitRefused;
    }
    const auto t_load = std::chrono::steady_clock::now();
    // TBB starts its worker threads (and loads its allocator) on the first parallel loop, which on a small scene would
    // be the render's: a trivial loop on another thread starts them while the scene loads.
    std::jthread start_pool([] { tbb::parallel_for(0, 256, [](int) {}); });  // joined also when the load throws
    LoadedScene loaded = load_scene_file(a.scene, lo);
    start_pool.join();
    for (const auto& w : loaded.warnings) spdlog::warn("{}", w);
    for (const auto& n : loaded.notes) spdlog::info("{}", n);
    const Scene& scene = loaded.scene;
    const auto t_loaded = std::chrono::steady_clock::now();
    const double load_s = std::chrono::duration<double>(t_loaded - t_load).count();
    const uint32_t spp = a.spp ? *a.spp : scene.settings.spp;
    std::optional<StoredRender> previous;
    if (resume_file) {
      previous = load_previous(*resume_file, a, scene);
      resume_file.reset();
    }

    const protocol::SamplingSettings sampling = sampling_settings(a, spp);
    RenderOptions ro;
    sampling.apply_to(ro);
    ro.spp = spp;
    ro.tile_size = a.tile_size;
    ro.variance = a.variance;
    ro.tile_budget = a.tile_budget;
    // A resumable file stays resumable when continued.
    ro.keep_state = a.resumable || (previous && previous->state.exact());
    ro.previous = previous ? &*previous : nullptr;
    if (a.replicates > 1 && ro.target_error <= 0.f && spp % a.replicates != 0)
      spdlog::warn("--replicates {} does not divide the sample count; the variance channels will be zero",
                   a.replicates);
    if (!a.crop.empty()) {
      ro.window = PixelWindow{a.crop[0], a.crop[1], a.crop[2], a.crop[3]};
      const PixelWindow full{0, 0, scene.width, scene.height};
      if (ro.window.empty() || !full.contains(ro.window)) {
        spdlog::error("--crop {} {} {} {} is empty or outside the {}x{} image", a.crop[0], a.crop[1], a.crop[2],
                      a.crop[3], scene.width, scene.height);
        return kExitRefused;
      }
    }
    ProgressBar bar(!a.quiet);
    ro.progress = [&](const RenderProgress& p) { bar.update(p); };
    InterruptGuard interrupts;
    ro.cancel = &InterruptGuard::flag();
    // The EXR is compressed while the render goes on, band by band as rows of tiles are final, so that only the last
    // rows are left when it ends. A partial file (float colours and the state channels) is laid out differently
    // and written at the end in one go, as is everything after a failed band.
    ExrWriteOptions layout;
    layout.half = a.half;
    layout.data_window = ro.window.empty() ? PixelWindow{0, 0, scene.width, scene.height} : ro.window;
    layout.display_window = PixelWindow{0, 0, scene.width, scene.height};
    ExrStream exr(layout);
    if (!a.multipart) ro.rows_final = [&](const Image& film, const RenderState& state, int y0, int y1) {
      if (exr.rows_written() != y0) return;  // stopped at a failed band
      try {
        Image band = image_rows(film, y0, y1);
        if (ro.keep_state) write_state_channels(state, band, size_t(y0) * size_t(film.width));
        exr.write_rows(band);
      } catch (const std::exception& e) {
        spdlog::debug("the EXR is written after the render instead: {}", e.what());
      }
    };
    RenderResult res = render(scene, ro);
    previous.reset();

    ExrWriteOptions wo;
    // A partial file keeps float colours: --resume copies its finished pixels bit for bit.
    wo.half = a.half && !res.cancelled;
    wo.data_window = res.window;
    wo.display_window = PixelWindow{0, 0, scene.width, scene.height};
    wo.metadata = sampling.metadata();  // the chosen strategies are recorded below
    wo.metadata["tessera:version"] = TESSERA_VERSION;
    wo.metadata["tessera:scene"] = a.scene;
    wo.metadata["tessera:sceneHash"] = scene.hash;
    wo.metadata["tessera:renderSeconds"] = std::to_string(res.seconds);
    wo.metadata["tessera:areaSampling"] = std::string(enum_name(scene.settings.area_sampling, kAreaSamplingNames));
    wo.metadata["tessera:envSampling"] = std::string(enum_name(scene.settings.env_sampling, kEnvSamplingNames));
    wo.metadata.merge(layer_metadata(scene, ro.layers));
    const size_t done = rendered_pixels(res.state);
    const size_t pixels_total = res.state.samples.size();
    if (res.cancelled) {
      wo.metadata["tessera:partial"] = std::to_string(done) + " of " + std::to_string(pixels_total) + " pixels";
    }
    if (res.cancelled || ro.keep_state) write_state_channels(res.state, res.image);
    const auto t_write = std::chrono::steady_clock::now();
    if (a.multipart) write_exr_multipart(a.output, res.image, wo, layer_parts(res.image));
    else exr.write(a.output, res.image, wo);
    if (!a.preview.empty()) write_png_srgb(a.preview, res.image);
    if (a.timing) {
      // The parts are spans between the same instants, so they add up to the total whatever the machine's load:
      // the set-up is everything between the load and the write that the threads did not do.
      const auto t_end = std::chrono::steady_clock::now();
      const double write_s = std::chrono::duration<double>(t_end - t_write).count();
      const double film_s = std::chrono::duration<double>(t_write - t_loaded).count() - res.parallel_seconds;
      const double total = std::chrono::duration<double>(t_end - t_load).count();
      const double outside = total - res.parallel_seconds;
      std::fprintf(stderr,
                   "timing: load %.4fs + film %.4fs + threaded render %.4fs on %d thread(s), idle %.4f thread-s "
                   "(%.2f%%) + write %.4fs = %.4fs; outside the threaded render %.4fs (%.2f%%)\n",
                   load_s, film_s, res.parallel_seconds, res.threads, res.idle_thread_seconds,
                   res.parallel_seconds > 0 ? 100.0 * res.idle_thread_seconds / (res.threads * res.parallel_seconds) : 0.0,
                   write_s, total, outside, total > 0 ? 100.0 * outside / total : 0.0);
    }
    if (res.counters.nonfinite > 0)
      spdlog::warn("{} sample(s) were NaN or Inf and were counted as zero", res.counters.nonfinite);
    const double pixels = double(res.window.width()) * double(res.window.height());
    const double mean_spp = pixels > 0 ? double(res.counters.camera) / pixels : 0.0;
    if (ro.target_error > 0.f)
      std::fprintf(stderr, "adaptive: target relative error %g, %u..%u spp, %.1f spp on average\n", ro.target_error,
                   ro.min_spp, ro.max_spp, mean_spp);
    char spp_text[32];
    if (ro.target_error > 0.f) std::snprintf(spp_text, sizeof spp_text, "%.1f", mean_spp);
    else std::snprintf(spp_text, sizeof spp_text, "%u", spp);
    std::fprintf(stderr, "%s: %dx%d px, %s spp (%llu samples), %.2fs load + %.2fs render, %.1f Mrays/s (%llu rays)\n",
                 a.output.c_str(), res.window.width(), res.window.height(), spp_text,
                 static_cast<unsigned long long>(res.counters.camera), load_s, res.seconds,
                 res.seconds > 0 ? double(res.counters.rays) / res.seconds * 1e-6 : 0.0,
                 static_cast<unsigned long long>(res.counters.rays));
    if (!res.cancelled) return kExitOk;
    std::fprintf(stderr, "%s: partial, %zu of %zu pixels rendered; finish it with: tessera render %s -o %s --resume %s\n",
                 a.output.c_str(), done, pixels_total, a.scene.c_str(), a.output.c_str(), a.output.c_str());
    return InterruptGuard::interrupted() ? kExitInterrupted : kExitBudget;
  } catch (const SceneError& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  } catch (const Refusal& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  } catch (const std::exception& e) {
    spdlog::error("render failed: {}", e.what());
    return kExitFailed;
  }
}

}  // namespace tessera::cli
