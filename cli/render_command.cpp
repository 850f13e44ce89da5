#include "cli/render_command.h"

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
  return c;
}

namespace {

std::string format_duration(double s) {
  char buf[64];
  if (s < 60) std::snprintf(buf, sizeof buf, "%.1fs", s);
  else if (s < 3600) std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  else std::snprintf(buf, sizeof buf, "%dh%02dm", int(s) / 3600, (int(s) / 60) % 60);
  return buf;
}

// A one-line progress bar on a terminal; on a pipe, a line at every 10% instead.
class ProgressBar {
 public:
  explicit ProgressBar(bool enabled) : enabled_(enabled), tty_(isatty(STDERR_FILENO)) {}
  void update(const RenderProgress& p) {
    if (!enabled_ || p.tiles_total == 0) return;
    const double frac = double(p.tiles_done) / p.tiles_total;
    const double eta = frac > 0 ? p.seconds * (1 - frac) / frac : 0;
    const double mrays = p.seconds > 0 ? double(p.rays) / p.seconds * 1e-6 : 0;
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = int(frac * kWidth);
      std::fprintf(stderr, "\r[%.*s%*s] %d/%d tiles  %.1f Mrays/s  ETA %s   ", filled,
                   "##############################", kWidth - filled, "", p.tiles_done, p.tiles_total, mrays,
                   format_duration(eta).c_str());
      if (p.tiles_done == p.tiles_total) std::fputc('\n', stderr);
    } else if (int(frac * 10) > last_decile_ || p.tiles_done == p.tiles_total) {
      last_decile_ = int(frac * 10);
      std::fprintf(stderr, "%3d%%  %d/%d tiles  %.1f Mrays/s  ETA %s\n", int(frac * 100), p.tiles_done, p.tiles_total,
                   mrays, format_duration(eta).c_str());
    }
  }

 private:
  bool enabled_, tty_;
  int last_decile_ = -1;
};

}  // namespace

int run_render(const RenderArgs& a) {
  try {
    // Warnings and errors go to stderr with the progress bar and the summary; stdout stays free for data.
    auto logger = spdlog::get("render");
    if (!logger) logger = spdlog::stderr_color_mt("render");
    spdlog::set_default_logger(logger);
    std::unique_ptr<tbb::global_control> limit;
    if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
    LoadOptions lo;
    lo.strict = a.strict;
    lo.force_direct = !a.integrator.empty();
    if (!a.asset_root.empty()) lo.asset_root = a.asset_root;
    lo.spp = a.spp;
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
                   {"tessera:spp", std::to_string(a.spp ? *a.spp : scene.settings.spp)},
                   {"tessera:seed", std::to_string(a.seed)},
                   {"tessera:renderSeconds", std::to_string(res.seconds)}};
    write_exr(a.output, res.image, wo);
    if (!a.preview.empty()) write_png_srgb(a.preview, res.image);
    if (res.counters.nonfinite > 0)
      spdlog::warn("{} sample(s) were NaN or Inf and were counted as zero", res.counters.nonfinite);
    std::fprintf(stderr, "%s: %dx%d px, %u spp (%llu samples), %.2fs load + %.2fs render, %.1f Mrays/s (%llu rays)\n",
                 a.output.c_str(), res.window.width(), res.window.height(), a.spp ? *a.spp : scene.settings.spp,
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
