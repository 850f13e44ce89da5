// Where the path tracer's error comes from: the variance of a pixel split bounce by bounce, for the default estimator
// and for variants that change one strategy (light selection, light sampling, MIS, roulette, stratification).
//
//   ./build/bench/variance_by_bounce [--scenes cbox_gi,cbox_env_light@path] [--res N] [--spp N] [--seeds M]
//                                    [--variants mis,nee,rw,area,no_rr,unpaired] [--threads N] [--out FILE]
//
// Method. A path of at most d bounces is a prefix of the path of at most d + 1 bounces drawn with the same seed: the
// sampler's dimensions are drawn in the same order and a vertex does the same work until the bounce limit stops it.
// So with Y_d the render (n spp, seed s) at max_depth d, C_d = Y_d - Y_(d-1) (C_0 = Y_0) is exactly what bounce d
// adds to that render: the emission a (d-1)-bounce path reaches plus the light gathered at vertex d - 1. Over M
// seeds, per pixel and channel, the sample variance of C_d weighted as relMSE (1 / (R^2 + 0.01), R the mean over
// the seeds of the deepest render) is the relMSE bounce d alone gives an n-spp render; the same of Y_d is the relMSE
// of paths up to d bounces, and the deepest Y is the full render's. What the components' sum misses is covariance
// between bounces. Each depth's CPU time shows what its bounce costs.
#include "bench/run_environment.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using namespace tessera;

namespace {

struct Args {
  std::vector<std::string> scenes = {"cbox_gi", "cbox_env_light@path"};
  std::vector<std::string> variants = {"mis", "nee", "rw", "area", "no_rr", "unpaired"};
  int res = 64;
  uint32_t spp = 16;
  int seeds = 16;
  int threads = 0;
  std::string out;
  std::string command;
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> v;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) v.push_back(item);
  return v;
}

// What each variant changes in the scene's settings, in one sentence for the report.
struct Variant {
  const char* name;
  const char* what;
  void (*apply)(IntegratorSettings&);
};

constexpr Variant kVariants[] = {
    {"mis", "the scene's own estimator (MIS, projected-solid-angle light sampling, roulette, paired draws)",
     [](IntegratorSettings&) {}},
    {"nee", "light sampling only (emitters found by BSDF rays do not count)",
     [](IntegratorSettings& s) { s.profile = PathProfile::kNee; }},
    {"rw", "no light sampling: BSDF sampling alone (the point light is still sampled)",
     [](IntegratorSettings& s) { s.profile = PathProfile::kRw; }},
    {"area", "area lights sampled uniformly by area instead of by projected solid angle",
     [](IntegratorSettings& s) { s.area_sampling = AreaSampling::kArea; }},
    {"no_rr", "no Russian roulette (paths end only at max_depth)", [](IntegratorSettings& s) { s.rr_threshold = 0.f; }},
    {"unpaired", "light draws not stratified jointly with the previous 2D draw",
     [](IntegratorSettings& s) { s.pair_light_with_pixel = false; }},
};

const Variant* find_variant(const std::string& name) {
  for (const Variant& v : kVariants)
    if (name == v.name) return &v;
  return nullptr;
}

// Scene NAME or NAME@path (its integrator replaced by the MIS path tracer, max_depth 16, roulette at 0.1, as
// bench/vs_cycles does), at res x res.
Scene load(const std::string& spec, int res) {
  const size_t at = spec.find('@');
  const std::string name = spec.substr(0, at);
  const std::string variant = at == std::string::npos ? "" : spec.substr(at + 1);
  Scene s = load_scene_file(fs::path(TESSERA_SOURCE_DIR) / "scenes" / (name + ".json"), LoadOptions{}).scene;
  if (variant == "path") {
    s.settings.integrator = IntegratorKind::kPath;
    s.settings.profile = PathProfile::kMis;
    s.settings.max_depth = 16;
    s.settings.rr_threshold = 0.1f;
  } else if (!variant.empty()) {
    throw std::invalid_argument(spec + ": unknown variant '" + variant + "' (known: path)");
  }
  if (s.settings.integrator != IntegratorKind::kPath)
    throw std::invalid_argument(spec + ": not a path-traced scene (add @path)");
  s.width = s.height = res;
  return s;
}

double cpu_now() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Per pixel and channel: sum and sum of squares of a quantity over the seeds.
struct Moments {
  std::vector<double> sum, sum2;
  explicit Moments(size_t n) : sum(n, 0.0), sum2(n, 0.0) {}
  void add(size_t i, double v) {
    sum[i] += v;
    sum2[i] += v * v;
  }
  // Mean over values of the unbiased sample variance, each weighted by w[i].
  double weighted_variance(int m, const std::vector<double>& w) const {
    double acc = 0;
    for (size_t i = 0; i < sum.size(); ++i) {
      const double mean = sum[i] / m;
      acc += std::max(0.0, (sum2[i] - m * mean * mean) / (m - 1)) * w[i];
    }
    return acc / double(sum.size());
  }
};

struct DepthRow {
  double component_var = 0;   // relMSE of C_d alone
  double cumulative_var = 0;  // relMSE of Y_d
  double energy = 0;          // sum over pixels of mean C_d
  double cpu = 0;             // CPU seconds of all renders at this depth
  double rays_per_sample = 0;
};

// The rows for one scene and variant: depth 0 .. the scene's max_depth.
std::vector<DepthRow> measure(const Scene& base, const Variant& v, const Args& a) {
  Scene s = base;
  v.apply(s.settings);
  const int depth_max = s.settings.max_depth;
  const size_t n = size_t(s.width) * size_t(s.height) * 3;
  // Images of the previous depth, one per seed, and each depth's moments of C_d and Y_d.
  std::vector<std::vector<float>> prev(size_t(a.seeds), std::vector<float>(n, 0.f));
  std::vector<Moments> comp(size_t(depth_max + 1), Moments(n)), cum(size_t(depth_max + 1), Moments(n));
  std::vector<DepthRow> rows(size_t(depth_max + 1));
  for (int d = 0; d <= depth_max; ++d) {
    s.settings.max_depth = d;
    for (int k = 0; k < a.seeds; ++k) {
      RenderOptions o;
      o.spp = a.spp;
      o.seed = uint64_t(1 + k);
      const double c0 = cpu_now();
      const RenderResult r = render(s, o);
      rows[size_t(d)].cpu += cpu_now() - c0;
      rows[size_t(d)].rays_per_sample += double(r.counters.rays) / (double(a.spp) * double(n / 3) * a.seeds);
      for (size_t i = 0; i < n; ++i) {
        const double y = r.image.rgb[i];
        comp[size_t(d)].add(i, y - prev[size_t(k)][i]);
        cum[size_t(d)].add(i, y);
        prev[size_t(k)][i] = float(y);
      }
    }
  }
  std::vector<double> w(n);
  for (size_t i = 0; i < n; ++i) {
    const double r = cum[size_t(depth_max)].sum[i] / a.seeds;
    w[i] = 1.0 / (r * r + 0.01);
  }
  for (int d = 0; d <= depth_max; ++d) {
    DepthRow& row = rows[size_t(d)];
    row.component_var = comp[size_t(d)].weighted_variance(a.seeds, w);
    row.cumulative_var = cum[size_t(d)].weighted_variance(a.seeds, w);
    for (size_t i = 0; i < n; ++i) row.energy += comp[size_t(d)].sum[i] / a.seeds;
  }
  return rows;
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string report_scene(const std::string& spec, const Args& a) {
  const Scene base = load(spec, a.res);
  std::ostringstream md;
  md << "\n## " << spec << "\n";
  struct Total {
    std::string name;
    double by_rays, by_cpu;  // relMSE x rays per sample, relMSE x CPU seconds
  };
  std::vector<Total> totals;
  for (const std::string& name : a.variants) {
    const Variant* v = find_variant(name);
    const std::vector<DepthRow> rows = measure(base, *v, a);
    const DepthRow& last = rows.back();
    double energy = 0, sum_var = 0, cpu_full = 0;
    for (const DepthRow& r : rows) {
      energy += r.energy;
      sum_var += r.component_var;
    }
    // The full render's CPU per seed: its own depth's renders (max_depth = the scene's).
    cpu_full = last.cpu / a.seeds;
    totals.push_back({name, last.cumulative_var * last.rays_per_sample, last.cumulative_var * cpu_full});
    md << "\n### " << name << ": " << v->what << "\n\n"
       << "Full render: relMSE " << fmt("%.3e", last.cumulative_var) << " at " << a.spp << " spp, "
       << fmt("%.3f", cpu_full) << " CPU s, " << fmt("%.2f", last.rays_per_sample)
       << " rays per sample; the bounces' variances sum to " << fmt("%.0f", 100.0 * sum_var / last.cumulative_var)
       << "% of it (the rest is covariance between bounces).\n\n"
       << "| bounces d | light share of C_d | relMSE of C_d | share of the full relMSE | relMSE of Y_d (paths up to d "
          "bounces) | CPU s per render at max_depth d |\n|---|---|---|---|---|---|\n";
    for (size_t d = 0; d < rows.size(); ++d) {
      const DepthRow& r = rows[d];
      md << "| " << d << " | " << fmt("%.1f%%", 100.0 * r.energy / energy) << " | " << fmt("%.3e", r.component_var)
         << " | " << fmt("%.1f%%", 100.0 * r.component_var / last.cumulative_var) << " | "
         << fmt("%.3e", r.cumulative_var) << " | " << fmt("%.3f", r.cpu / a.seeds) << " |\n";
    }
    std::fprintf(stderr, "variance_by_bounce: %s %s done\n", spec.c_str(), name.c_str());
  }
  md << "\nCost at equal error, relative to " << totals.front().name
     << " (lower is better): relMSE x rays per sample (does not depend on the machine's load) / relMSE x CPU seconds:";
  for (const Total& t : totals)
    md << " " << t.name << " " << fmt("%.2f", t.by_rays / totals.front().by_rays) << " / "
       << fmt("%.2f", t.by_cpu / totals.front().by_cpu) << ";";
  md << "\n";
  return md.str();
}

[[noreturn]] void usage(const char* prog) {
  std::fprintf(stderr,
               "usage: %s [--scenes A,B@path] [--res N] [--spp N] [--seeds M] [--variants mis,nee,rw,area,no_rr,unpaired]"
               " [--threads N] [--out FILE]\n",
               prog);
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 0; i < argc; ++i) a.command += (i ? " " : "") + std::string(i ? argv[i] : "./build/bench/variance_by_bounce");
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) usage(argv[0]);
      return argv[++i];
    };
    if (k == "--scenes") a.scenes = split(next());
    else if (k == "--variants") a.variants = split(next());
    else if (k == "--res") a.res = std::stoi(next());
    else if (k == "--spp") a.spp = uint32_t(std::stoul(next()));
    else if (k == "--seeds") a.seeds = std::stoi(next());
    else if (k == "--threads") a.threads = std::stoi(next());
    else if (k == "--out") a.out = next();
    else usage(argv[0]);
  }
  for (const std::string& v : a.variants)
    if (!find_variant(v)) {
      std::fprintf(stderr, "variance_by_bounce: unknown variant '%s' (known: mis, nee, rw, area, no_rr, unpaired)\n",
                   v.c_str());
      return 2;
    }
  if (a.seeds < 2 || a.res < 1 || a.spp < 1) usage(argv[0]);
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
  std::ostringstream md;
  md << "variance_by_bounce: the path tracer's variance split by bounce (bench/variance_by_bounce.cpp)\n"
     << "command: " << a.command << "\n"
     << "commit: " << bench::commit_description(TESSERA_SOURCE_DIR, TESSERA_CONFIGURE_COMMIT) << "\n"
     << "machine: " << bench::cpu_model() << ", " << std::thread::hardware_concurrency()
     << " logical CPUs, load average " << bench::load_average() << " at start\n"
     << "settings: " << a.res << "x" << a.res << " px, " << a.spp << " spp per render, " << a.seeds
     << " seeds; relMSE weights 1 / (R^2 + 0.01), R the mean of the seeds' full renders\n"
     << "C_d = Y_d - Y_(d-1): what bounce d adds (Y_d: the render at max_depth d, same seed); light share: C_d's part "
        "of the image's sum\n";
  try {
    for (const std::string& spec : a.scenes) md << report_scene(spec, a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "variance_by_bounce: %s\n", e.what());
    return 1;
  }
  std::fputs(md.str().c_str(), stdout);
  if (!a.out.empty()) std::ofstream(a.out) << md.str();
  return 0;
}
