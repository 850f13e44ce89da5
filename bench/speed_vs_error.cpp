// Speed against error: for each project scene, error against a reference as a function of render time,
// equal-error comparisons of the sampling strategies and BVH builds, adaptive sampling (--target-error) against
// uniform sample counts, the environment-map fix before/after, and predicted against measured error. Writes
// docs/speed-vs-error.md, its data files and a gnuplot script, and runs gnuplot on it.
//
//   ./build/bench/speed_vs_error [--out DIR] [--scale F] [--max-spp N] [--ref-spp N] [--repeats N] [--threads N]
//
// Runs being compared are interleaved (every strategy at one sample count, then the next count) and each timing is
// the median of --repeats runs, because the machine is shared.
#include "bench/error_metrics.h"
#include "bench/run_environment.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <ctime>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using namespace tessera;
using tessera::bench::cpu_model;

namespace {

// What the adaptive table shows and why (written from the measurements of the first full run; the numbers in the
// table itself are regenerated every time).
// A converged reference: `spp` samples at seed 1000 in 8 replicates, with variance channels (its own error).
RenderResult render_reference(const Scene& s, uint32_t spp) {
  RenderOptions ro;
  ro.spp = spp;
  ro.seed = 1000;
  ro.variance = true;
  ro.replicates = 8;
  return render(s, ro);
}

constexpr const char* kAdaptiveDiscussion = R"(How to read it (from the run of commit d0386d4; see the table for the current figures):

- Equal-error sampling cannot beat uniform sampling on mean error by much in theory: if pixel i needs
  n_i = s_i^2 / E^2 samples to reach error E (s_i its per-sample deviation), the total is sum s_i^2 / E^2, exactly
  what uniform sampling needs to reach the same *mean* squared error E^2 (the allocation that minimises mean error
  is n_i proportional to s_i, not s_i^2). Adaptive sampling gains where the per-pixel bounds bite: easy pixels stop
  at the minimum while stratification makes them converge faster than 1/n, and hard ones stop at the maximum.
- It wins where difficulty varies across the picture: the Cornell boxes with a point light or an area light (K = 1,
  M = 8: 20-50% and 54-78% less time at equal relMSE; soft-shadow and edge pixels get the samples, flat walls stop
  early), and sky_sun with M = 32 (5-21%).
- M must fit the target: a pixel's rule never stops before about 1/E samples, so M = 32 only wastes samples on
  pixels that needed 8 at E = 0.2 (cbox_no_light: -36%), while M = 8 lets pixels stop on the evidence of 8 samples.
- It loses on cbox_env_light, whose every pixel has the same kind of noise (visibility of a constant sky through
  the open front): there is nothing to redistribute, and the per-pixel estimate only adds scatter. With M = 8 a
  dark corner whose first 8 samples all miss the sky has zero sample variance and stops at once (about 15% of that
  image at E = 0.2, holding over 90% of its error; -580%); the rule's 1/n term (core/sampling/adaptive.h) cannot know the
  size of an event it has not seen, so M must be large enough to see the events that matter. M = 32 brings E = 0.2
  to -8%; at tighter targets the conservative estimate (next point) still over-samples by 2x.
- K = 4 replicates give an unbiased estimate (see the predicted-against-measured table) but lose more to weaker
  stratification and to premature stops from a 3-degree-of-freedom estimate than they gain by not over-sampling;
  the conservative K = 1 estimate (3-30x the true variance here) is the better default for --target-error.

)";

// What the path-tracing tables show (written from the measurements of the first full run).
constexpr const char* kPathDiscussion = R"(## Findings (from the run of commit 06be5e1 with the scenes of 56fbfe8; the tables above are regenerated every time)

- MIS has the lowest error at equal time on `veach_mis`: relMSE 0.0041 against 0.091 (NEE) and 0.12 (RW) at MIS's
  64-spp CPU time; NEE needs 16x and RW 29x MIS's time to reach its error. NEE fails on the near-mirror plates
  (light samples almost never fall in their lobes, and BSDF-sampled hits of the lights do not count), RW on the small
  lights (BSDF rays rarely hit them).
- On `cbox_gi` (diffuse walls, one light) MIS and NEE are equal (0.00413 / 0.00413; a BSDF-sampled hit of the light
  from a diffuse wall gets a tiny MIS weight) and RW needs 72x the time.
- Russian roulette (rr_threshold 0.1) saves time at equal error: without it, `cbox_gi` traces 10.7 instead of 6.9 rays
  per sample (paths run to max_depth 16) and needs 1.41x the time for the same relMSE; `veach_mis` (max_depth 8,
  dark backdrop) 1.18x. At equal sample count roulette costs a little variance (0.00413 against 0.00371 on `cbox_gi`).
- `cbox_glass` converges slowest (relMSE 0.030 at 128 spp against 0.0020 for `cbox_gi`): caustics under the glass
  sphere are found only by BSDF sampling from the floor through the glass to the small light.
)";

// Independent renders summed per row of the predicted-against-measured table. In cbox_area_light ten pixels (the
// sliver of the light at a pixel's edge) carry 75-81% of the variance at 16-64 spp, and both the variance channel
// and the squared error there are heavy-tailed: 8 renders gave ratios of 0.79 and 1.23 for K = 4, while 64 renders
// (direct check: empirical variance over the seeds against the mean variance channel) gave 0.93-1.02.
constexpr int kPredictionSeeds = 64;

// Samples per pixel, summed over a row's renders, that every row of the error-against-time sweep averages its errors
// over (row at n spp: max(repeats, kSweepSamples / n) renders, with seeds no other row uses). In cbox_area_light two
// pixels hold a sliver of the light seen edge-on (hit with probability 0.0056 per sample, value 28 against a mean of
// 0.16): one hit at 16 spp is an error of 1.6 there and 0.01-0.03 of the frame's relMSE. With 3 renders per row and
// every row reusing seeds 1-3 (each row a prefix of the next), the table showed whether seeds 1-3 happened to hit
// those pixels in their first n samples (8 spp: none, 0.0021; 16 and 32 spp: the same three hits, 0.0146 and 0.0033)
// instead of the expected error. 1024 samples see about 11 such hits per row.
constexpr uint32_t kSweepSamples = 1024;

struct Args {
  fs::path out = fs::path(TESSERA_SOURCE_DIR) / "docs";
  double scale = 0.25;      // resolution factor applied to every scene
  uint32_t max_spp = 256;   // sweep 1, 2, 4, ... max_spp
  uint32_t ref_spp = 4096;  // reference sample count
  int repeats = 3;          // timing repeats (median)
  int threads = 0;
  bool path_tracing = false;  // write the path-tracing report (speed-vs-error-path.md) instead of the main one
  std::string command;
};

// ---- metrics -------------------------------------------------------------------------------------------------

// Predicted relMSE of img against ref from the variance channels: mean of (Var(I) + Var(R)) / (R^2 + 0.01).
double predicted_rel_mse(const Image& img, const Image* ref_for_weights, bool include_ref_var) {
  const Image& ref = ref_for_weights ? *ref_for_weights : img;
  const size_t n = size_t(img.width) * size_t(img.height);
  double s = 0;
  const char* names[3] = {"variance.R", "variance.G", "variance.B"};
  for (size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const double r = ref.rgb[3 * i + size_t(c)];
      double v = img.extra.at(names[c])[i];
      if (include_ref_var) v += ref.extra.at(names[c])[i];
      s += v / (r * r + 0.01);
    }
  return s / (3.0 * double(n));
}

// ---- scenes and runs -----------------------------------------------------------------------------------------

struct Variant {
  std::string name;
  std::optional<AreaSampling> area;
  std::optional<EnvSampling> env;
  std::optional<SplitMethod> bvh;
  bool raw_env_distribution = false;
};

Scene load(const std::string& scene_name, const Variant& v, double scale) {
  LoadOptions lo;
  lo.area_sampling = v.area;
  lo.env_sampling = v.env;
  lo.bvh = v.bvh;
  Scene s = load_scene_file(fs::path(TESSERA_SOURCE_DIR) / "scenes" / (scene_name + ".json"), lo).scene;
  s.width = std::max(1, int(std::lround(s.width * scale)));
  s.height = std::max(1, int(std::lround(s.height * scale)));
  if (v.raw_env_distribution && s.environment) {
    s.environment->raw_pixel_distribution = true;
    s.environment->finish();
  }
  return s;
}

struct Run {
  double seconds = 0;      // median wall time
  double cpu_seconds = 0;  // median process CPU time (all threads), less sensitive to other jobs on the machine
  Metrics m;
  double mean_spp = 0;
  RenderResult last;
};

double cpu_now() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Renders every (scene, options) pair `repeats` times, interleaved (pair 0, pair 1, ..., then again), so slow
// phases of a shared machine hit all of them alike. Repeat r uses seed + r, so the repeats are independent renders:
// times are medians, errors the mean over the repeats (RMSE: root of the mean square), because one render's relMSE
// can hinge on a handful of pixels (a sliver of a bright light inside a pixel).
std::vector<Run> run_interleaved(const std::vector<const Scene*>& scenes, const std::vector<RenderOptions>& opts,
                                 const std::vector<const Image*>& refs, int repeats) {
  const size_t n = scenes.size();
  std::vector<Run> runs(n);
  std::vector<std::vector<double>> wall(n), cpu(n);
  std::vector<double> camera(n, 0.0), rmse2(n, 0.0);
  for (int r = 0; r < repeats; ++r)
    for (size_t i = 0; i < n; ++i) {
      RenderOptions o = opts[i];
      o.seed += uint64_t(r);
      const double c0 = cpu_now();
      runs[i].last = render(*scenes[i], o);
      cpu[i].push_back(cpu_now() - c0);
      wall[i].push_back(runs[i].last.seconds);
      const Metrics m = metrics(runs[i].last.image, *refs[i]);
      runs[i].m.rel_mse += m.rel_mse / repeats;
      runs[i].m.p99 += m.p99 / repeats;
      rmse2[i] += m.rmse * m.rmse / repeats;
      camera[i] += double(runs[i].last.counters.camera) / repeats;
    }
  for (size_t i = 0; i < n; ++i) {
    runs[i].seconds = median(wall[i]);
    runs[i].cpu_seconds = median(cpu[i]);
    runs[i].m.rmse = std::sqrt(rmse2[i]);
    runs[i].mean_spp = camera[i] / (double(scenes[i]->width) * double(scenes[i]->height));
  }
  return runs;
}

Run run(const Scene& s, RenderOptions o, const Image& ref, int repeats) {
  return run_interleaved({&s}, {o}, {&ref}, repeats)[0];
}

// Every scene of `ss` (variants of one scene) at `spp`, interleaved, against the same reference.
std::vector<Run> run_variants(const std::vector<Scene>& ss, uint32_t spp, uint64_t seed, const Image& ref, int repeats) {
  std::vector<const Scene*> sp;
  std::vector<RenderOptions> os;
  std::vector<const Image*> rs;
  for (const Scene& sc : ss) {
    RenderOptions o;
    o.spp = spp;
    o.seed = seed;
    sp.push_back(&sc);
    os.push_back(o);
    rs.push_back(&ref);
  }
  return run_interleaved(sp, os, rs, repeats);
}

struct Point {
  uint32_t spp;
  double seconds, rel_mse, rmse, p99, mean_spp, cpu_seconds;
};

// Time at which a curve (sorted by time, error decreasing) reaches error `target`: interpolated in log-log between
// the bracketing points, or extrapolated from the nearest end with the ideal slope (error ~ 1/time for a squared
// error such as relMSE, `squared`; ~ 1/sqrt(time) for p99, a relative error).
double time_to_reach(const std::vector<Point>& c, double target, bool cpu, double Point::*err = &Point::rel_mse) {
  auto t = [cpu](const Point& p) { return cpu ? p.cpu_seconds : p.seconds; };
  const bool squared = err == &Point::rel_mse;
  for (size_t i = 0; i + 1 < c.size(); ++i) {
    const double a = c[i].*err, b = c[i + 1].*err;
    if ((a >= target && b <= target) || (a <= target && b >= target)) {
      if (a == b) return t(c[i]);
      const double f = std::log(target / a) / std::log(b / a);
      return std::exp(std::log(t(c[i])) + f * (std::log(t(c[i + 1])) - std::log(t(c[i]))));
    }
  }
  const Point& e = (target < c.back().*err) ? c.back() : c.front();
  const double ratio = e.*err / target;
  return t(e) * (squared ? ratio : ratio * ratio);
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string shell(const std::string& cmd) {
  std::string out;
  if (FILE* p = popen(cmd.c_str(), "r")) {
    char buf[256];
    while (fgets(buf, sizeof buf, p)) out += buf;
    pclose(p);
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

void log(const std::string& s) {
  std::fprintf(stderr, "%s\n", s.c_str());
  std::fflush(stderr);
}


// ---- path tracing ------------------------------------------------------------------------------------------------

// relMSE a curve (sorted by CPU time) reaches at CPU time t: log-log interpolation, or the ideal 1/time slope beyond.
double error_at_time(const std::vector<Point>& c, double t) {
  for (size_t i = 0; i + 1 < c.size(); ++i)
    if (c[i].cpu_seconds <= t && t <= c[i + 1].cpu_seconds) {
      const double f = std::log(t / c[i].cpu_seconds) / std::log(c[i + 1].cpu_seconds / c[i].cpu_seconds);
      return std::exp(std::log(c[i].rel_mse) + f * (std::log(c[i + 1].rel_mse) - std::log(c[i].rel_mse)));
    }
  const Point& e = t < c.front().cpu_seconds ? c.front() : c.back();
  return e.rel_mse * e.cpu_seconds / t;
}

// The path tracer's report: error against time on the path-traced scenes, the three profiles at equal time, and
// Russian roulette on and off. Writes speed-vs-error-path.md beside the main report.
// Writes a report to `file`, keeping the section "Against Blender Cycles" of the file's previous version as it is:
// that section comes from bench/vs_cycles/run.sh, not from this bench.
void write_report(const fs::path& file, const std::string& text) {
  const std::string cycles_heading = "\n## Against Blender Cycles";
  std::string kept;
  if (std::ifstream old(file); old) {
    const std::string previous((std::istreambuf_iterator<char>(old)), std::istreambuf_iterator<char>());
    if (const size_t at = previous.find(cycles_heading); at != std::string::npos) kept = previous.substr(at);
  }
  std::ofstream(file) << text << kept;
  log("wrote " + file.string());
}

int path_tracing_report(const Args& a, const fs::path& data, const std::string& stamp, const std::string& machine) {
  struct PathScene {
    std::string name;
    fs::path file;
  };
  const fs::path own = fs::path(TESSERA_SOURCE_DIR) / "scenes";
  const fs::path course = own / "course";
  const std::vector<PathScene> scenes = {{"sphere", course / "sphere.json"},
                                         {"glass_sphere", course / "glass_sphere.json"},
                                         {"cbox_gi", own / "cbox_gi.json"},
                                         {"cbox_glass", own / "cbox_glass.json"},
                                         {"veach_mis", own / "veach_mis.json"}};
  auto load_scaled = [&](const PathScene& ps) {
    Scene s = load_scene_file(ps.file).scene;
    s.width = std::max(1, int(std::lround(s.width * a.scale)));
    s.height = std::max(1, int(std::lround(s.height * a.scale)));
    return s;
  };
  std::vector<uint32_t> sweep;
  for (uint32_t s = 1; s <= a.max_spp; s *= 2) sweep.push_back(s);
  std::ostringstream md;
  md << "# Speed against error: the path tracer\n\n"
     << "Regenerated by `" << a.command << "` (bench/speed_vs_error.cpp; the rest of the report is "
     << "[speed-vs-error.md](speed-vs-error.md)).\n\n"
     << "- Machine: " << machine << "; shared with other jobs, so runs being compared are interleaved and every time "
     << "is the median of " << a.repeats << " runs. Times are process CPU seconds (all threads).\n"
     << "- Code: " << stamp << ".\n"
     << "- Resolution: every scene at " << a.scale << " x its own. References: " << a.ref_spp << " spp with the "
     << "scene's own profile and 8 independent replicates (own relMSE estimate stated). Metrics as in the main report "
     << "(relMSE = mean (I-R)^2/(R^2+0.01) over pixels and channels).\n"
     << "- Scenes: the course's `sphere.json` (diffuse sphere in a white environment plus the default point light) and "
     << "`glass_sphere.json` (glass, eta 1.8, under the sky map), and the project's `cbox_gi`, `cbox_glass`, "
     << "`veach_mis` (scenes/).\n\n"
     << "## Error against time (MIS, the scenes' settings)\n\n"
     << "| scene | pixels | reference relMSE | spp | CPU (s) | relMSE | RMSE | p99 | rays per sample |\n"
     << "|---|---|---|---|---|---|---|---|---|\n";
  std::map<std::string, Image> refs;
  std::map<std::string, std::vector<Point>> curves;
  for (const PathScene& ps : scenes) {
    const Scene s = load_scaled(ps);
    log("path-tracing reference " + ps.name);
    const RenderResult ref = render_reference(s, a.ref_spp);
    refs[ps.name] = ref.image;
    for (uint32_t spp : sweep) {
      RenderOptions o;
      o.spp = spp;
      o.seed = 1;
      const Run r = run(s, o, ref.image, a.repeats);
      curves[ps.name].push_back({spp, r.seconds, r.m.rel_mse, r.m.rmse, r.m.p99, r.mean_spp, r.cpu_seconds});
      md << "| " << ps.name << " | " << s.width << "x" << s.height << " | "
         << fmt("%.2e", predicted_rel_mse(ref.image, nullptr, false)) << " | " << spp << " | "
         << fmt("%.4f", r.cpu_seconds) << " | " << fmt("%.4g", r.m.rel_mse) << " | " << fmt("%.4g", r.m.rmse) << " | "
         << fmt("%.4g", r.m.p99) << " | "
         << fmt("%.2f", double(r.last.counters.rays) / double(std::max<uint64_t>(1, r.last.counters.camera))) << " |\n";
    }
  }

  // Profiles at equal time, and roulette on/off: sweeps of each variant, interleaved per sample count.
  struct VariantRow {
    std::string label;
    std::optional<PathProfile> profile;
    std::optional<float> rr;
  };
  auto compare = [&](const std::string& title, const std::string& scene, const std::vector<VariantRow>& variants,
                     const std::string& note) {
    const PathScene& ps = *std::find_if(scenes.begin(), scenes.end(), [&](const PathScene& x) { return x.name == scene; });
    std::vector<Scene> ss;
    for (const VariantRow& v : variants) {
      Scene s = load_scaled(ps);
      if (v.profile) s.settings.profile = *v.profile;
      if (v.rr) s.settings.rr_threshold = *v.rr;
      ss.push_back(std::move(s));
    }
    log("path-tracing comparison: " + title + " on " + scene);
    std::vector<std::vector<Point>> c(variants.size());
    std::vector<double> rays(variants.size(), 0.0);
    for (uint32_t spp : sweep) {
      if (spp < 4) continue;
      const std::vector<Run> runs = run_variants(ss, spp, 11, refs[scene], a.repeats);
      for (size_t k = 0; k < runs.size(); ++k) {
        c[k].push_back({spp, runs[k].seconds, runs[k].m.rel_mse, runs[k].m.rmse, runs[k].m.p99, runs[k].mean_spp,
                        runs[k].cpu_seconds});
        rays[k] = double(runs[k].last.counters.rays) / double(std::max<uint64_t>(1, runs[k].last.counters.camera));
      }
    }
    // Reference point: the first variant at 64 spp (or the sweep's end).
    const Point& base = *std::find_if(c[0].begin(), c[0].end(), [&](const Point& p) { return p.spp >= std::min(64u, a.max_spp); });
    md << "### " << title << ": " << scene << "\n\n" << note << "\n\n"
       << "| variant | relMSE at " << base.spp << " spp | CPU (s) at " << base.spp << " spp | rays per sample | relMSE at "
       << fmt("%.3g", base.cpu_seconds) << " CPU s (" << variants[0].label << "'s " << base.spp << "-spp time) | CPU time to reach "
       << variants[0].label << "'s " << base.spp << "-spp relMSE, ratio |\n|---|---|---|---|---|---|\n";
    for (size_t k = 0; k < variants.size(); ++k) {
      const Point& p = *std::find_if(c[k].begin(), c[k].end(), [&](const Point& q) { return q.spp == base.spp; });
      md << "| " << variants[k].label << " | " << fmt("%.4g", p.rel_mse) << " | " << fmt("%.3f", p.cpu_seconds) << " | "
         << fmt("%.2f", rays[k]) << " | " << fmt("%.4g", error_at_time(c[k], base.cpu_seconds)) << " | "
         << fmt("%.2f", time_to_reach(c[k], base.rel_mse, true) / base.cpu_seconds) << " |\n";
    }
    md << "\n";
  };
  md << "\n## Profiles at equal time\n\n"
     << "Each profile renders the same scene (converging to the same image; core/render/path_integrator_test.cpp checks "
     << "that); errors against the MIS reference. Equal time = the relMSE each profile's curve reaches at MIS's "
     << "64-spp CPU time (log-log interpolation).\n\n";
  const std::vector<VariantRow> profiles = {{"MIS", PathProfile::kMis, {}}, {"NEE", PathProfile::kNee, {}},
                                            {"RW", PathProfile::kRw, {}}};
  compare("Profiles", "veach_mis", profiles,
          "Four plates from near-mirror (alpha 0.005) to rough (0.2) reflecting four lights of equal power, radii 0.04 "
          "to 0.6: light sampling fails on the smooth plates with large lights, BSDF sampling on rough plates with "
          "small lights.");
  compare("Profiles", "cbox_gi", profiles, "The global-illumination box (one rectangular light, diffuse walls).");
  md << "## Russian roulette\n\n"
     << "rr_threshold 0.1 (the format's default: below it a path survives with probability equal to its throughput's "
     << "largest channel) against 0 (no roulette; paths end only at max_depth).\n\n";
  const std::vector<VariantRow> rr = {{"rr 0.1", {}, 0.1f}, {"no roulette", {}, 0.f}};
  compare("Roulette", "cbox_gi", rr, "max_depth 16, walls of albedo 0.05-0.73.");
  compare("Roulette", "veach_mis", rr, "max_depth 8: metal plates and a dark backdrop (albedo 0.1).");
  md << "\n" << kPathDiscussion;
  write_report(a.out / "speed-vs-error-path.md", md.str());
  (void)data;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 0; i < argc; ++i) {
    if (i) a.command += ' ';
    a.command += argv[i];
  }
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", k.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (k == "--out") a.out = next();
    else if (k == "--scale") a.scale = std::stod(next());
    else if (k == "--max-spp") a.max_spp = uint32_t(std::stoul(next()));
    else if (k == "--ref-spp") a.ref_spp = uint32_t(std::stoul(next()));
    else if (k == "--repeats") a.repeats = std::stoi(next());
    else if (k == "--threads") a.threads = std::stoi(next());
    else if (k == "--path-tracing") a.path_tracing = true;
    else {
      std::fprintf(stderr, "usage: %s [--out DIR] [--scale F] [--max-spp N] [--ref-spp N] [--repeats N] [--threads N] [--path-tracing]\n", argv[0]);
      return 2;
    }
  }
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
  const fs::path data = a.out / "speed-vs-error";
  fs::create_directories(data);
  const std::string commit = shell("git -C " TESSERA_SOURCE_DIR " rev-parse --short HEAD 2>/dev/null");
  const std::string dirty = shell("git -C " TESSERA_SOURCE_DIR " status --porcelain --untracked-files=no 2>/dev/null");
  const std::string machine = cpu_model() + ", " + std::to_string(std::thread::hardware_concurrency()) + " threads";
  std::string stamp = "commit ";
  stamp += commit.empty() ? std::string("unknown") : commit;
  if (!dirty.empty()) stamp += " (+ local changes)";
  stamp += ", ";
  stamp += machine;
  if (a.path_tracing) return path_tracing_report(a, data, stamp, machine);

  const std::vector<std::string> scenes = {"cbox_no_light", "cbox_no_light_refraction", "cbox_area_light",
                                           "cbox_env_light", "sky_sun"};
  std::vector<uint32_t> sweep;
  for (uint32_t s = 1; s <= a.max_spp; s *= 2) sweep.push_back(s);

  std::ostringstream md;
  md << "# Speed against error\n\n"
     << "Regenerated by `" << a.command << "` (" << "bench/speed_vs_error.cpp"
     << "; plots by gnuplot from `docs/speed-vs-error/plots.gp`). The path tracer's figures (path-traced scenes, "
     << "profiles MIS / NEE / RW at equal time, Russian roulette) are in [speed-vs-error-path.md](speed-vs-error-path.md), "
     << "written by the same program with `--path-tracing`.\n\n"
     << "- Machine: " << machine << " (`/proc/cpuinfo`, `nproc`); shared with other jobs, so runs being compared are "
     << "interleaved and every time is the median of " << a.repeats << " runs.\n"
     << "- Code: " << stamp << ".\n"
     << "- Resolution: every scene at " << a.scale << " x its own resolution (reduced so the whole report runs in "
     << "minutes on this machine).\n"
     << "- Error metrics, against the reference, over pixels and RGB channels: relMSE = mean (I-R)^2/(R^2+0.01); RMSE;"
     << " p99 = 99th percentile over pixels of the per-pixel relative error sqrt(mean_c (I-R)^2/(R^2+0.01)).\n"
     << "- Error against time: the row at n spp averages its errors over max(" << a.repeats << ", " << kSweepSamples
     << " / n) renders whose seeds no other row uses (times: their median), so that every row sees the rare samples "
     << "that dominate relMSE (the sliver of the area light inside two pixels of cbox_area_light, hit with probability "
     << "0.006 per sample).\n"
     << "- References: none of the five scenes has a closed-form pixel value (every pixel integrates over its area "
     << "across edges, and light over occluded area lights or maps), so each reference is a " << a.ref_spp
     << " spp render with 8 independent replicates (unbiased error estimate; core/sampling/adaptive.h), with its own "
     << "estimated relMSE stated.\n\n";

  // ---- 1. error against time per scene, and predicted vs measured --------------------------------------------
  std::map<std::string, Image> refs;
  std::map<std::string, double> ref_err;
  std::map<std::string, std::vector<Point>> curves;
  md << "## Error against time, default strategies\n\n"
     << "| scene | pixels | reference relMSE (own estimate) | spp | wall (s) | CPU (s) | relMSE | RMSE | p99 |\n|---|---|---|---|---|---|---|---|---|\n";
  std::ostringstream pred_md;
  pred_md << "## Predicted against measured error\n\n"
          << "Predicted relMSE = mean over pixels of (Var(I) + Var(R)) / (R^2 + 0.01) from the variance channels; "
          << "measured = relMSE against the reference. With one stratified sequence per pixel (the default) the "
          << "variance channel is the i.i.d. estimate sample variance / n, which the Owen-scrambled Sobol sampler "
          << "beats; with K independent replicates (`--replicates K`) it is unbiased. Estimates from the default "
          << "sampler's own samples (sibling-block differences, extrapolated over the block sizes) are measured in "
          << "[error-estimates.md](error-estimates.md), which also shows why none can be unbiased and why an unbiased "
          << "one costs stratification.\n\n"
          << "Each row sums " << kPredictionSeeds << " renders with different seeds (the aggregate); the last column "
          << "is the range of the ratio over the single renders.\n\n"
          << "| scene | spp | replicates | predicted | measured | measured / predicted | single renders |\n"
          << "|---|---|---|---|---|---|---|\n";
  int pred_rows = 0, pred_within = 0;
  for (const auto& name : scenes) {
    const Scene s = load(name, {}, a.scale);
    log("reference " + name);
    const RenderResult ref = render_reference(s, a.ref_spp);
    refs[name] = ref.image;
    ref_err[name] = predicted_rel_mse(ref.image, nullptr, false);
    std::vector<Point>& c = curves[name];
    for (uint32_t spp : sweep) {
      RenderOptions o;
      o.spp = spp;
      o.seed = uint64_t(spp) << 20;  // rows share no seeds (and so no samples)
      const Run r = run(s, o, ref.image, std::max(a.repeats, int(kSweepSamples / spp)));
      c.push_back({spp, r.seconds, r.m.rel_mse, r.m.rmse, r.m.p99, r.mean_spp, r.cpu_seconds});
      md << "| " << name << " | " << s.width << "x" << s.height << " | " << fmt("%.2e", ref_err[name]) << " | " << spp
         << " | " << fmt("%.4f", r.seconds) << " | " << fmt("%.4f", r.cpu_seconds) << " | " << fmt("%.4g", r.m.rel_mse) << " | " << fmt("%.4g", r.m.rmse)
         << " | " << fmt("%.4g", r.m.p99) << " |\n";
    }
    std::ofstream dat(data / (name + ".dat"));
    dat << "# spp wall_seconds relMSE RMSE p99 cpu_seconds\n";
    for (const Point& p : c)
      dat << p.spp << ' ' << p.seconds << ' ' << p.rel_mse << ' ' << p.rmse << ' ' << p.p99 << ' ' << p.cpu_seconds << '\n';
    // Predicted vs measured at two sample counts, one sequence and 4 or 8 replicates, each summed over
    // kPredictionSeeds independent renders: one render's relMSE is dominated by a few pixels (the sliver of the area
    // light at the edge of a pixel), so a single render's ratio scatters by a factor of 2-3 either way.
    for (uint32_t spp : {16u, 64u})
      for (uint32_t k : {1u, 4u, 8u}) {
        double pred = 0, meas = 0, lo = 1e300, hi = 0;
        for (int seed = 0; seed < kPredictionSeeds; ++seed) {
          RenderOptions o;
          o.spp = spp;
          o.seed = 7 + uint64_t(seed);
          o.variance = true;
          o.replicates = k;
          const RenderResult r = render(s, o);
          const double p1 = predicted_rel_mse(r.image, &ref.image, true), m1 = metrics(r.image, ref.image).rel_mse;
          pred += p1 / kPredictionSeeds;
          meas += m1 / kPredictionSeeds;
          lo = std::min(lo, m1 / p1);
          hi = std::max(hi, m1 / p1);
        }
        const double ratio = meas / pred;
        if (k > 1) {
          ++pred_rows;
          if (std::abs(ratio - 1.0) <= 0.2) ++pred_within;
        }
        pred_md << "| " << name << " | " << spp << " | " << k << " | " << fmt("%.4g", pred) << " | " << fmt("%.4g", meas)
                << " | " << fmt("%.3f", ratio) << " | " << fmt("%.2f", lo) << " - " << fmt("%.2f", hi) << " |\n";
      }
  }
  md << "\n![error against time](speed-vs-error/error_vs_time.svg)\n\n"
     << "Plotted: relative RMS error sqrt(relMSE) against median wall time, log-log, with the ideal 1/sqrt(time) "
     << "slope drawn through each scene's 1-spp point.\n\n";
  md << pred_md.str() << "\nWith replicates (K = 4 or 8) the aggregate prediction is within 20% of the measured error in "
     << pred_within << " of " << pred_rows << " rows.\n\n";

  // ---- 2. strategies at equal error ---------------------------------------------------------------------------
  struct Comparison {
    std::string title, scene;
    std::vector<Variant> variants;  // first = default
  };
  const std::vector<Comparison> comps = {
      {"Area light on cbox_area_light (small light): auto (default) vs solid angle vs area", "cbox_area_light",
       {{"auto", AreaSampling::kAuto, {}, {}}, {"solid_angle", AreaSampling::kSolidAngle, {}, {}},
        {"area", AreaSampling::kArea, {}, {}}}},
      {"Area light on cbox_large_light (light over most of the ceiling): auto (default) vs solid angle vs area",
       "cbox_large_light",
       {{"auto", AreaSampling::kAuto, {}, {}}, {"solid_angle", AreaSampling::kSolidAngle, {}, {}},
        {"area", AreaSampling::kArea, {}, {}}}},
      {"Environment on sky_sun: MIS (default) vs importance vs cosine vs uniform", "sky_sun",
       {{"mis", {}, EnvSampling::kMis, {}}, {"importance", {}, EnvSampling::kImportance, {}},
        {"cosine", {}, EnvSampling::kCosine, {}}, {"uniform", {}, EnvSampling::kUniform, {}}}},
      {"Environment on cbox_env_light (constant map: MIS and importance fall back to cosine)", "cbox_env_light",
       {{"mis", {}, EnvSampling::kMis, {}}, {"cosine", {}, EnvSampling::kCosine, {}},
        {"uniform", {}, EnvSampling::kUniform, {}}}},
      {"Environment distribution on sky_sun: bilinear support (fixed) vs raw pixels (before the fix), MIS", "sky_sun",
       {{"bilinear-support mis", {}, EnvSampling::kMis, {}}, {"raw-pixel mis", {}, EnvSampling::kMis, {}, true}}},
      {"Environment distribution on sky_sun: bilinear support (fixed) vs raw pixels, importance only", "sky_sun",
       {{"bilinear-support importance", {}, EnvSampling::kImportance, {}},
        {"raw-pixel importance", {}, EnvSampling::kImportance, {}, true}}},
      {"BVH: SAH (default) vs median split, cbox_area_light (36 triangles)", "cbox_area_light",
       {{"sah", {}, {}, SplitMethod::kSah}, {"median", {}, {}, SplitMethod::kMedian}}},
      {"BVH: SAH (default) vs median split, sky_sun", "sky_sun",
       {{"sah", {}, {}, SplitMethod::kSah}, {"median", {}, {}, SplitMethod::kMedian}}},
  };
  md << "## Strategies at equal error\n\n"
     << "Each strategy renders the sweep (1.." << a.max_spp << " spp, all strategies at one count before the next "
     << "count); the table gives the time each needs to reach the relMSE the default reaches at "
     << std::min<uint32_t>(64, a.max_spp) << " spp (log-log interpolation; beyond a curve's end, extrapolated with "
     << "the ideal relMSE ~ 1/time), and the ratio to the default (> 1: slower than the default). Times are process "
     << "CPU seconds (all threads; less disturbed by the other jobs on this shared machine than wall time), with "
     << "the wall-time ratio beside them. Plots: sqrt(relMSE) against CPU seconds.\n\n";
  int plot_id = 0;
  std::vector<std::pair<std::string, std::vector<std::string>>> comp_plots;
  for (const Comparison& cmp : comps) {
    log("comparison: " + cmp.title);
    if (!refs.count(cmp.scene)) {  // a scene outside the five (its reference made the same way)
      log("reference " + cmp.scene);
      RenderOptions ro;
      ro.spp = a.ref_spp;
      ro.seed = 1000;
      ro.replicates = 8;
      refs[cmp.scene] = render(load(cmp.scene, {}, a.scale), ro).image;
    }
    std::vector<Scene> ss;
    for (const Variant& v : cmp.variants) ss.push_back(load(cmp.scene, v, a.scale));
    std::vector<std::vector<Point>> cs(ss.size());
    for (uint32_t spp : sweep) {
      const std::vector<Run> runs = run_variants(ss, spp, 1, refs[cmp.scene], a.repeats);
      for (size_t k = 0; k < ss.size(); ++k) {
        const Run& r = runs[k];
        cs[k].push_back({spp, r.seconds, r.m.rel_mse, r.m.rmse, r.m.p99, r.mean_spp, r.cpu_seconds});
      }
    }
    const uint32_t at = std::min<uint32_t>(64, a.max_spp);
    double target = 0;
    for (const Point& p : cs[0])
      if (p.spp == at) target = p.rel_mse;
    const double t0 = time_to_reach(cs[0], target, true), w0 = time_to_reach(cs[0], target, false);
    md << "### " << cmp.title << "\n\n| strategy | relMSE at " << at << " spp | CPU s at " << at
       << " spp | CPU s to relMSE " << fmt("%.3g", target) << " | ratio to default (CPU) | ratio to default (wall) |\n"
       << "|---|---|---|---|---|---|\n";
    std::vector<std::string> files;
    for (size_t k = 0; k < ss.size(); ++k) {
      double rm = 0, tm = 0;
      for (const Point& p : cs[k])
        if (p.spp == at) {
          rm = p.rel_mse;
          tm = p.cpu_seconds;
        }
      const double t = time_to_reach(cs[k], target, true), w = time_to_reach(cs[k], target, false);
      md << "| " << cmp.variants[k].name << (k == 0 ? " (default)" : "") << " | " << fmt("%.4g", rm) << " | "
         << fmt("%.4f", tm) << " | " << fmt("%.4f", t) << " | " << fmt("%.2f", t / t0) << " | " << fmt("%.2f", w / w0)
         << " |\n";
      const std::string file = "cmp" + std::to_string(plot_id) + "_" + std::to_string(k) + ".dat";
      std::ofstream dat(data / file);
      dat << "# " << cmp.variants[k].name << "\n# spp wall_seconds relMSE RMSE p99 cpu_seconds\n";
      for (const Point& p : cs[k])
        dat << p.spp << ' ' << p.seconds << ' ' << p.rel_mse << ' ' << p.rmse << ' ' << p.p99 << ' ' << p.cpu_seconds << '\n';
      files.push_back(file + "|" + cmp.variants[k].name);
    }
    md << "\n![" << cmp.title << "](speed-vs-error/cmp" << plot_id << ".svg)\n\n";
    comp_plots.push_back({cmp.title, files});
    ++plot_id;
  }

  // ---- 3. adaptive sampling against uniform spp ---------------------------------------------------------------
  struct AdaptiveConfig {
    uint32_t replicates, min_spp;
  };
  const std::vector<AdaptiveConfig> configs = {{1, 8}, {1, 32}, {4, 32}};
  const uint32_t adaptive_max = 4 * a.max_spp;
  md << "## --target-error against uniform spp\n\n"
     << "Adaptive runs: `--target-error E --min-spp M --max-spp " << adaptive_max << " --error-floor 0.1 "
     << "--replicates K` (the floor matches relMSE's +0.01: both judge pixels darker than 0.1 by absolute error) "
     << "for three settings: K = 1 (one stratified sequence per pixel, the default; conservative error estimate) "
     << "with M = 8 and M = 32, and K = 4 (unbiased but noisier estimate, weaker stratification) with M = 32. Times "
     << "are CPU seconds (median of " << a.repeats << " renders with different seeds; errors are their mean). The "
     << "uniform columns give the CPU time the uniform sweep above needs for the same relMSE, and for the same p99 "
     << "(the 99th-percentile pixel error, which is what a per-pixel target bounds); saved = 1 - adaptive / uniform "
     << "(negative: adaptive costs more).\n\n"
     << "| scene | K | M | E | mean spp | CPU (s) | relMSE | uniform CPU s, same relMSE | saved | p99 | uniform CPU s, "
     << "same p99 | saved |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::ofstream adat(data / "adaptive.dat");
  adat << "# scene K M E mean_spp cpu_seconds relMSE uniform_cpu_seconds_relMSE p99 uniform_cpu_seconds_p99\n";
  for (const auto& name : scenes) {
    const Scene s = load(name, {}, a.scale);
    for (const AdaptiveConfig& cfg : configs)
      for (float e : {0.2f, 0.1f, 0.05f}) {
        log("adaptive " + name + " K=" + std::to_string(cfg.replicates) + " M=" + std::to_string(cfg.min_spp) + " E=" +
            fmt("%g", e));
        RenderOptions o;
        o.seed = 1;
        o.target_error = e;
        o.min_spp = cfg.min_spp;
        o.max_spp = adaptive_max;
        o.error_floor = 0.1f;
        o.replicates = cfg.replicates;
        const Run r = run(s, o, refs[name], a.repeats);
        const double tu = time_to_reach(curves[name], r.m.rel_mse, true);
        const double tp = time_to_reach(curves[name], r.m.p99, true, &Point::p99);
        md << "| " << name << " | " << cfg.replicates << " | " << cfg.min_spp << " | " << e << " | "
           << fmt("%.1f", r.mean_spp) << " | " << fmt("%.4f", r.cpu_seconds) << " | " << fmt("%.4g", r.m.rel_mse)
           << " | " << fmt("%.4f", tu) << " | " << fmt("%.0f%%", 100.0 * (1.0 - r.cpu_seconds / tu)) << " | "
           << fmt("%.4g", r.m.p99) << " | " << fmt("%.4f", tp) << " | "
           << fmt("%.0f%%", 100.0 * (1.0 - r.cpu_seconds / tp)) << " |\n";
        adat << name << ' ' << cfg.replicates << ' ' << cfg.min_spp << ' ' << e << ' ' << r.mean_spp << ' '
             << r.cpu_seconds << ' ' << r.m.rel_mse << ' ' << tu << ' ' << r.m.p99 << ' ' << tp << '\n';
      }
  }
  md << "\n" << kAdaptiveDiscussion;

  // ---- plots --------------------------------------------------------------------------------------------------
  {
    std::ofstream gp(data / "plots.gp");
    gp << "# Written by bench/speed_vs_error; run from docs/speed-vs-error/: gnuplot plots.gp\n"
       << "set terminal svg size 900,600 dynamic font 'sans,12'\nset logscale xy\nset grid\nset key outside right\n"
       << "set xlabel 'wall time (s), " << machine << "'\nset ylabel 'relative RMS error sqrt(relMSE)'\n";
    gp << "set output 'error_vs_time.svg'\nset title 'Error against time, default strategies (" << stamp << ")' noenhanced\nplot \\\n";
    for (size_t i = 0; i < scenes.size(); ++i) {
      const Point& p0 = curves[scenes[i]].front();
      gp << "  '" << scenes[i] << ".dat' using 2:(sqrt($3)) with linespoints lw 2 title '" << scenes[i] << "' noenhanced, \\\n"
         << "  " << std::sqrt(p0.rel_mse) << "*sqrt(" << p0.seconds << "/x) with lines dt 2 lc " << i + 1
         << " notitle" << (i + 1 < scenes.size() ? ", \\\n" : "\n");
    }
    gp << "set xlabel 'CPU seconds (all threads), " << machine << "'\n";
    for (size_t c = 0; c < comp_plots.size(); ++c) {
      gp << "set output 'cmp" << c << ".svg'\nset title '" << comp_plots[c].first << "' noenhanced\nplot \\\n";
      const auto& files = comp_plots[c].second;
      for (size_t k = 0; k < files.size(); ++k) {
        const std::string f = files[k].substr(0, files[k].find('|')), t = files[k].substr(files[k].find('|') + 1);
        gp << "  '" << f << "' using 6:(sqrt($3)) with linespoints lw 2 title '" << t << "' noenhanced"
           << (k + 1 < files.size() ? ", \\\n" : "\n");
      }
    }
  }
  const int rc = std::system(("cd '" + data.string() + "' && gnuplot plots.gp").c_str());
  if (rc != 0) log("gnuplot failed (is gnuplot-nox installed?)");

  write_report(a.out / "speed-vs-error.md", md.str());
  return 0;
}
