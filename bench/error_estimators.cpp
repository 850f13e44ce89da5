// Error estimates for the default sampler: what each candidate predicts against the measured
// error, and what it costs in relMSE against the default (one Owen-scrambled sequence per pixel), on the five scenes
// of docs/speed-vs-error.md. Prints markdown tables (docs/error-estimates.md holds runs of it).
//
//   ./build/bench/error_estimators [--scale F] [--seeds S] [--ref-spp N] [--spp N,N,...] [--scenes a,b,...]
//                                  [--replicates 0|1] [--sweep MAX_SPP] [--adaptive E,E,...] [--closed-forms]
//
// Candidates from the default render's own samples (its colours unchanged, relMSE cost 0): the i.i.d. variance
// s^2/n (today's variance channel), the half difference h(n/2) and three extrapolations over the block sizes
// (core/sampling/block_differences.h): the rate pooled over the top three levels, the rate over two doublings of the top four
// levels, and the same from the four levels below the top. Each extrapolation is also applied to the levels averaged
// over the S renders ("expected levels"): a per-pixel estimate with no noise at all, which shows what extrapolating
// the levels can reach at best. Candidates that change the samples: K = 2 and K = 4 independent replicates of n/K
// samples (`--replicates K`), whose variance channel is unbiased.
//
// For every pixel, the measured error is the mean over S renders (seeds 7 .. 7+S-1) of the squared error against a
// reference (ref-spp samples, 8 replicates, seed 1000) and the predicted one the mean of the estimate plus the
// reference's own variance; relMSE weights 1/(R^2 + 0.01) as in the report. Columns: relMSE cost = measured relMSE /
// the default's; aggregate = predicted / measured relMSE over the frame; p50 and p99 = the median and 99th
// percentile over pixels of the predicted per-pixel relative error sqrt(mean_c pred/(R^2+0.01)) divided by the same
// quantile of the measured one (per-pixel distribution; 1 = exact, the S renders leave about 1/sqrt(2S) of noise).
// The renders at several spp are prefixes of one stream per seed (a render at n samples is the first n samples of
// one at 2n), so the rows of one scene share their renders.
//
// --closed-forms: no scene; integrands of the first one or two 2D draws of one pixel's PixelSampler, the true
// variance of the n-sample mean over S seeds (default 4096) against the mean of each estimate.
#include "bench/error_metrics.h"
#include "core/sampling/block_differences.h"
#include "core/render/path_integrator.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <array>
#include <cstdio>
#include <filesystem>
#include <span>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace tessera;

namespace {

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string t; std::getline(in, t, ',');) out.push_back(t);
  return out;
}

double quantile(std::vector<double> v, double q) {
  const size_t k = size_t(q * double(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + ptrdiff_t(k), v.end());
  return v[k];
}

// Per pixel and channel (index 3 i + c): summed squared error and summed predicted variance of the mean over renders.
struct Tally {
  std::vector<double> se, pred;
  explicit Tally(size_t n) : se(n, 0.0), pred(n, 0.0) {}
};

struct Row {
  double cost, aggregate, p50, p99;
};

// Frame figures of a tally against the reference (its variance added to every prediction); `base_se`: the default's
// squared errors, for the cost.
Row summarise(const Tally& t, const Image& ref, const std::vector<double>& base_se) {
  const size_t np = size_t(ref.width) * size_t(ref.height);
  const char* names[3] = {"variance.R", "variance.G", "variance.B"};
  double meas = 0, pred = 0, base = 0;
  std::vector<double> pm(np), pp(np);
  for (size_t i = 0; i < np; ++i) {
    double a = 0, b = 0;
    for (size_t c = 0; c < 3; ++c) {
      const double r = ref.rgb[3 * i + c], w = 1.0 / (r * r + 0.01), vr = ref.extra.at(names[c])[i];
      a += t.se[3 * i + c] * w;
      b += (t.pred[3 * i + c] + vr) * w;
      base += base_se[3 * i + c] * w;
    }
    meas += a;
    pred += b;
    pm[i] = std::sqrt(a / 3);
    pp[i] = std::sqrt(b / 3);
  }
  return {meas / base, pred / meas, quantile(pp, 0.5) / quantile(pm, 0.5), quantile(pp, 0.99) / quantile(pm, 0.99)};
}

// The uniform sweep of the report for one scene, by both protocols: the old one (3 renders per row, seeds 1-3 at
// every spp, so each row's samples are a prefix of the next row's) and the current one (max(3, 1024 / spp) renders
// per row, seeds no other row uses; bench/speed_vs_error.cpp). Prints mean relMSE and p99 per row.
void sweep(const std::string& name, const Scene& s, const Image& ref, uint32_t max_spp) {
  std::printf("| scene | spp | relMSE, 3 renders, seeds 1-3 (old) | renders (current) | relMSE (current) | p99 (current) |\n"
              "|---|---|---|---|---|---|\n");
  for (uint32_t spp = 1; spp <= max_spp; spp *= 2) {
    const auto mean_of = [&](uint64_t seed0, int renders) {
      Metrics sum;
      for (int r = 0; r < renders; ++r) {
        RenderOptions o;
        o.spp = spp;
        o.seed = seed0 + uint64_t(r);
        const Metrics m = metrics(render(s, o).image, ref);
        sum.rel_mse += m.rel_mse / renders;
        sum.p99 += m.p99 / renders;
      }
      return sum;
    };
    const int renders = std::max(3, int(1024 / spp));
    const Metrics old = mean_of(1, 3), now = mean_of(uint64_t(spp) << 20, renders);
    std::printf("| %s | %u | %.4g | %d | %.4g | %.4g |\n", name.c_str(), spp, old.rel_mse, renders, now.rel_mse, now.p99);
    std::fflush(stdout);
  }
}

// Block extrapolations of a pixel channel's variance of the mean from its levels h(1) .. h(n/2).
enum Ext { kPooled, kTwoDoubling, kTwoDoublingBelow, kExtCount };
const char* const kExtNames[kExtCount] = {"rate pooled over the top 3 levels", "rate over two doublings, top 4 levels",
                                          "rate over two doublings, 4 levels below the top"};
double extrapolate(Ext e, std::span<const double> levels) {
  switch (e) {
    case kPooled: return BlockDifferences::pooled_rate(levels);
    case kTwoDoubling: return BlockDifferences::two_doubling_rate(levels);
    default: return BlockDifferences::two_doubling_rate_below(levels);
  }
}

// Candidates from one render's samples: the i.i.d. estimate, h(n/2), then the extrapolations.
constexpr int kOwnCount = 2 + kExtCount;
std::string own_name(int e) {
  if (e == 0) return "i.i.d. s^2/n (today)";
  if (e == 1) return "half difference h(n/2)";
  return kExtNames[e - 2];
}

// --target-error's rule (core/sampling/adaptive.h: rounds of 16, 32, ... 1024 samples; stop when sqrt(var + (u s/n)^2) / s
// <= E with s = max(mean luminance, 0.1), u = 1 today) with estimates of var on luminance: the i.i.d. one (today),
// the rate over two doublings with today's unseen-event term, and the same with that term a tenth as large (u =
// 0.1; with an estimate that is not inflated, the rule's s/n term alone stops every pixel at about 1/E samples).
// Simulated here, sample by sample, so the core is unchanged. Prints, per rule and target, the mean spp, the
// measured p99 (as the report defines it) and the uniform spp that reaches the same p99 (log-log interpolation over
// uniform renders at 16 .. 1024 spp; saved = 1 - adaptive / uniform in samples, which on this machine are steadier
// than times).
void adaptive(const std::string& name, const Scene& s, const Image& ref, const std::vector<double>& targets) {
  const size_t np = size_t(s.width) * size_t(s.height);
  std::vector<std::pair<double, double>> uniform;  // (spp, p99)
  for (uint32_t spp = 16; spp <= 1024; spp *= 2) {
    RenderOptions o;
    o.spp = spp;
    o.seed = 5000 + spp;
    uniform.push_back({double(spp), metrics(render(s, o).image, ref).p99});
  }
  const auto uniform_spp = [&](double p99) {
    for (size_t i = 0; i + 1 < uniform.size(); ++i) {
      const auto [n0, e0] = uniform[i];
      const auto [n1, e1] = uniform[i + 1];
      if ((e0 >= p99 && e1 <= p99) || (e0 <= p99 && e1 >= p99))
        return e0 == e1 ? n0 : std::exp(std::log(n0) + std::log(p99 / e0) / std::log(e1 / e0) * std::log(n1 / n0));
    }
    const auto [n, e] = p99 < uniform.back().second ? uniform.back() : uniform.front();
    return n * (e / p99) * (e / p99);  // ideal: error ~ 1 / sqrt(n)
  };
  const char* rules[3] = {"i.i.d. (today)", "two doublings", "two doublings, unseen term / 10"};
  for (int rule = 0; rule < 3; ++rule)
    for (double target : targets) {
      Image img = Image::make(s.width, s.height);
      std::vector<double> spp(np);
      tbb::parallel_for(size_t(0), np, [&](size_t i) {
        const int px = int(i % size_t(s.width)), py = int(i / size_t(s.width));
        RayCounters rc;
        BlockDifferences bd;
        glm::dvec3 sum(0.0);
        double y2 = 0;
        uint32_t n = 0;
        for (uint32_t end = 16;; end = std::min(1024U, 2 * end)) {
          for (; n < end; ++n) {
            PixelSampler sp = pixel_sampler(9, px, py, n, 1);
            const Ray r = s.camera.generate_pixel(px, py, sp.next_2d(), s.width, s.height);
            const Vec3 L = trace_sample(s, r, sp, rc);
            const double y = 0.2126 * L.x + 0.7152 * L.y + 0.0722 * L.z;
            sum += glm::dvec3(L);
            y2 += y * y;
            bd.add(y);
          }
          const double ym = (0.2126 * sum.x + 0.7152 * sum.y + 0.0722 * sum.z) / n;
          const double var = rule == 0 ? std::max(0.0, y2 - n * ym * ym) / (n - 1.0) / n : bd.two_doubling();
          const double scale = std::max(ym, 0.1), unseen = (rule == 2 ? 0.1 : 1.0) * scale / n;
          if (n >= 1024 || std::sqrt(var + unseen * unseen) / scale <= target) break;
        }
        img.set(px, py, Vec3(sum / double(n)));
        spp[i] = n;
      });
      double mean = 0;
      for (double v : spp) mean += v / double(np);
      const double p99 = metrics(img, ref).p99, u = uniform_spp(p99);
      std::printf("| %s | %s | %.3g | %.1f | %.4g | %.1f | %.0f%% |\n", name.c_str(), rules[rule], target, mean, p99, u,
                  100.0 * (1.0 - mean / u));
      std::fflush(stdout);
    }
}

// --levels: the level profile of the scene's median pixels (those whose measured relative error at the largest spp
// lies between the 40th and 60th percentile; green channel): the geometric mean over them of h(2b) / h(b) from the
// levels averaged over the renders at the largest spp, and of the measured Var_2n / Var_n between successive spp
// (the decay the extrapolations have to guess; the reference's own variance is in both).
void print_levels(const std::string& name, const Image& ref, const std::vector<uint32_t>& counts,
                  const std::vector<std::vector<Tally>>& own, const std::vector<std::vector<std::vector<double>>>& sums,
                  int seeds) {
  const size_t np = size_t(ref.width) * size_t(ref.height), last = counts.size() - 1;
  std::vector<double> err(np);
  for (size_t i = 0; i < np; ++i) {
    const double r = ref.rgb[3 * i + 1];
    err[i] = own[last][0].se[3 * i + 1] / (r * r + 0.01);
  }
  const double lo = quantile(err, 0.4), hi = quantile(err, 0.6);
  const size_t levels = sums[last][1].size();
  std::vector<double> log_level(levels > 0 ? levels - 1 : 0, 0.0), log_var(last, 0.0);
  std::vector<size_t> n_level(log_level.size(), 0), n_var(last, 0);
  size_t band = 0;
  for (size_t i = 0; i < np; ++i) {
    if (err[i] < lo || err[i] > hi) continue;
    ++band;
    const std::vector<double>& l = sums[last][3 * i + 1];
    for (size_t j = 0; j + 1 < l.size(); ++j)
      if (l[j] > 0 && l[j + 1] > 0) {
        log_level[j] += std::log(l[j + 1] / l[j]);
        ++n_level[j];
      }
    for (size_t c = 0; c < last; ++c) {
      const double a = own[c][0].se[3 * i + 1], b = own[c + 1][0].se[3 * i + 1];
      if (a > 0 && b > 0 && counts[c + 1] == 2 * counts[c]) {
        log_var[c] += std::log(b / a);
        ++n_var[c];
      }
    }
  }
  std::printf("| %s | %zu of %zu, %d renders |", name.c_str(), band, np, seeds);
  for (size_t j = 0; j < log_level.size(); ++j)
    std::printf("%s %.3f", j ? "," : "", n_level[j] ? std::exp(log_level[j] / double(n_level[j])) : 0.0);
  std::printf(" |");
  for (size_t c = 0; c < log_var.size(); ++c)
    std::printf("%s %.3f", c ? "," : "", n_var[c] ? std::exp(log_var[c] / double(n_var[c])) : 0.0);
  std::printf(" |\n");
  std::fflush(stdout);
}

// --closed-forms: integrands of one pixel's sample stream whose variance is taken over `seeds` seeds (each an
// independently scrambled stream), against the mean of each estimate, at n = 16 .. 256. The first five use the
// first 2D draw u (the pixel's position in a render); the last multiplies an edge in u by an edge in the second
// draw v, as a shadow boundary seen across a pixel multiplies pixel and light coordinates; the i.i.d. row draws
// independent uniform numbers instead of the sampler.
void closed_forms(int seeds) {
  struct Integrand {
    const char* name;
    double (*f)(Vec2, Vec2);
  };
  const Integrand fs[] = {
      {"linear x", [](Vec2 u, Vec2) { return double(u.x); }},
      {"bilinear x y", [](Vec2 u, Vec2) { return double(u.x) * u.y; }},
      {"edge x < 0.3", [](Vec2 u, Vec2) { return u.x < 0.3f ? 1.0 : 0.0; }},
      {"slanted edge x + 0.37 y < 0.61", [](Vec2 u, Vec2) { return u.x + 0.37f * u.y < 0.61f ? 1.0 : 0.0; }},
      {"disc of radius 0.3", [](Vec2 u, Vec2) {
         const double dx = u.x - 0.5, dy = u.y - 0.5;
         return dx * dx + dy * dy < 0.09 ? 1.0 : 0.0;
       }},
      {"edge in u x edge in v", [](Vec2 u, Vec2 v) { return (u.x < 0.3f ? 1.0 : 0.0) * (v.y < 0.6f ? 1.0 : 0.0); }},
      {"i.i.d. uniform", nullptr},
  };
  std::printf("| integrand | n | true variance of the mean | i.i.d. s^2/n | half difference |");
  for (const char* e : kExtNames) std::printf(" %s |", e);
  std::printf("\n|---|---|---|---|---|---|---|---|\n");
  for (const Integrand& f : fs)
    for (uint32_t n = 16; n <= 256; n *= 2) {
      std::vector<std::array<double, kOwnCount + 1>> per(size_t(seeds), std::array<double, kOwnCount + 1>{});  // estimates, mean
      tbb::parallel_for(0, seeds, [&](int s) {
        BlockDifferences bd;
        double sum = 0, sum2 = 0;
        uint32_t state = hash_u32(uint32_t(s) * 7919U + 3U);
        for (uint32_t i = 0; i < n; ++i) {
          double x;
          if (f.f) {
            PixelSampler p(uint64_t(s) * 7919 + 3, 5, 9, i);
            const Vec2 u = p.next_2d(), v = p.next_2d();
            x = f.f(u, v);
          } else {
            state = hash_u32(state + 0x9e3779b9U);
            x = u32_to_unit(state);
          }
          bd.add(x);
          sum += x;
          sum2 += x * x;
        }
        const double mean = sum / n;
        auto& e = per[size_t(s)];
        e[0] = std::max(0.0, sum2 - n * mean * mean) / (n - 1.0) / n;
        e[1] = bd.half_difference();
        const std::vector<double> levels = bd.levels();
        for (int x = 0; x < kExtCount; ++x) e[size_t(2 + x)] = extrapolate(Ext(x), levels);
        e[kOwnCount] = mean;
      });
      double m = 0, m2 = 0;
      std::array<double, kOwnCount> est{};
      for (const auto& e : per) {
        m += e[kOwnCount] / seeds;
        m2 += e[kOwnCount] * e[kOwnCount] / seeds;
        for (int x = 0; x < kOwnCount; ++x) est[size_t(x)] += e[size_t(x)] / seeds;
      }
      const double var = (m2 - m * m) * seeds / (seeds - 1.0);
      std::printf("| %s | %u | %.3g |", f.name, n, var);
      for (double e : est) std::printf(" %.2f |", e / var);
      std::printf("\n");
      std::fflush(stdout);
    }
}

}  // namespace

int main(int argc, char** argv) {
  double scale = 0.25;
  int seeds = 0;  // 0: 16 renders (4096 seeds with --closed-forms)
  uint32_t ref_spp = 4096;
  std::vector<std::string> spps = {"16", "64"};
  bool replicates = true;  // --replicates 0: skip the replicate rows (two more renders per seed and spp)
  bool closed = false;
  bool levels_only = false;  // --levels: the median pixels' level profile instead of the estimate rows
  uint32_t sweep_max = 0;  // > 0: print the uniform sweep 1 .. sweep_max spp instead (see sweep())
  std::vector<double> targets;  // non-empty: simulate --target-error at these targets instead (see adaptive())
  std::vector<std::string> scenes = {"cbox_no_light", "cbox_no_light_refraction", "cbox_area_light", "cbox_env_light",
                                     "sky_sun"};
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--closed-forms" || k == "--levels") {
      (k == "--levels" ? levels_only : closed) = true;
      continue;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "usage: %s [--scale F] [--seeds S] [--ref-spp N] [--spp N,N] [--scenes a,b] [--replicates 0|1] [--sweep N] [--adaptive E,E] [--closed-forms] [--levels]\n", argv[0]);
      return 2;
    }
    const std::string v = argv[++i];
    if (k == "--scale") scale = std::stod(v);
    else if (k == "--seeds") seeds = std::stoi(v);
    else if (k == "--ref-spp") ref_spp = uint32_t(std::stoul(v));
    else if (k == "--spp") spps = split(v);
    else if (k == "--scenes") scenes = split(v);
    else if (k == "--sweep") sweep_max = uint32_t(std::stoul(v));
    else if (k == "--replicates") replicates = v != "0";
    else if (k == "--adaptive")
      for (const std::string& t : split(v)) targets.push_back(std::stod(t));
    else {
      std::fprintf(stderr, "unknown option %s\n", k.c_str());
      return 2;
    }
  }
  if (closed) {
    closed_forms(seeds > 1 ? seeds : 4096);
    return 0;
  }
  if (seeds <= 0) seeds = 16;
  std::vector<uint32_t> counts;
  for (const std::string& t : spps) {
    const uint32_t n = uint32_t(std::stoul(t));
    if (n < 8 || (n & (n - 1)) != 0) {
      std::fprintf(stderr, "--spp takes powers of two from 8\n");
      return 2;
    }
    counts.push_back(n);
  }
  std::sort(counts.begin(), counts.end());
  if (!targets.empty())
    std::printf("| scene | rule | E | mean spp | p99 | uniform spp, same p99 | saved |\n|---|---|---|---|---|---|---|\n");
  else if (levels_only)
    std::printf("| scene | pixels | h(2b) / h(b) for b = 1, 2, 4, ... | measured Var_2n / Var_n for n = %u, %u, ... |\n"
                "|---|---|---|---|\n", counts.front(), 2 * counts.front());
  else if (sweep_max == 0)
    std::printf("| scene | spp | estimate | relMSE cost | aggregate predicted / measured | p50 | p99 |\n"
              "|---|---|---|---|---|---|---|\n");
  for (const std::string& name : scenes) {
    Scene s = load_scene_file(fs::path(TESSERA_SOURCE_DIR) / "scenes" / (name + ".json")).scene;
    s.width = std::max(1, int(std::lround(s.width * scale)));
    s.height = std::max(1, int(std::lround(s.height * scale)));
    RenderOptions ro;
    ro.spp = ref_spp;
    ro.seed = 1000;
    ro.replicates = 8;
    ro.variance = true;
    const Image ref = render(s, ro).image;
    if (sweep_max > 0) {
      sweep(name, s, ref, sweep_max);
      continue;
    }
    if (!targets.empty()) {
      adaptive(name, s, ref, targets);
      continue;
    }
    const size_t np = size_t(s.width) * size_t(s.height), nc = counts.size();
    // Per sample count: the default sampler's tallies (the same samples, in the same order, as render()), and per
    // pixel and channel the levels summed over the renders (for the expected-level rows).
    std::vector<std::vector<Tally>> own(nc, std::vector<Tally>(kOwnCount, Tally(3 * np)));
    std::vector<std::vector<std::vector<double>>> level_sums(nc, std::vector<std::vector<double>>(3 * np));
    tbb::parallel_for(size_t(0), np, [&](size_t i) {
      const int px = int(i % size_t(s.width)), py = int(i / size_t(s.width));
      RayCounters rc;
      for (int seed = 0; seed < seeds; ++seed) {
        BlockDifferences bd[3];
        double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
        size_t next = 0;
        for (uint32_t k = 0; k < counts.back(); ++k) {
          PixelSampler sp = pixel_sampler(7 + uint64_t(seed), px, py, k, 1);
          const Ray r = s.camera.generate_pixel(px, py, sp.next_2d(), s.width, s.height);
          const Vec3 L = trace_sample(s, r, sp, rc);
          for (int c = 0; c < 3; ++c) {
            bd[c].add(L[c]);
            sum[c] += L[c];
            sum2[c] += double(L[c]) * double(L[c]);
          }
          if (k + 1 != counts[next]) continue;
          const double n = double(k + 1);
          for (size_t c = 0; c < 3; ++c) {
            const double mean = sum[c] / n, d = mean - ref.rgb[3 * i + c];
            const std::vector<double> levels = bd[c].levels();
            std::vector<double>& ls = level_sums[next][3 * i + c];
            ls.resize(levels.size(), 0.0);
            for (size_t j = 0; j < levels.size(); ++j) ls[j] += levels[j];
            double est[kOwnCount] = {std::max(0.0, sum2[c] - n * mean * mean) / (n - 1.0) / n,
                                     bd[c].half_difference()};
            for (int e = 0; e < kExtCount; ++e) est[2 + e] = extrapolate(Ext(e), levels);
            for (size_t e = 0; e < size_t(kOwnCount); ++e) {
              own[next][e].se[3 * i + c] += d * d / seeds;
              own[next][e].pred[3 * i + c] += est[e] / seeds;
            }
          }
          ++next;
        }
      }
    });
    if (levels_only) {
      print_levels(name, ref, counts, own, level_sums, seeds);
      continue;
    }
    for (size_t ci = 0; ci < nc; ++ci) {
      const uint32_t n = counts[ci];
      const std::vector<double>& base = own[ci][0].se;
      for (int e = 0; e < kOwnCount; ++e) {
        const Row r = summarise(own[ci][size_t(e)], ref, base);
        std::printf("| %s | %u | %s | %.2f | %.3f | %.2f | %.2f |\n", name.c_str(), n, own_name(e).c_str(), r.cost,
                    r.aggregate, r.p50, r.p99);
      }
      // The extrapolations of the levels' mean over the renders: no per-render noise left.
      for (int e = 0; e < kExtCount; ++e) {
        Tally t(3 * np);
        t.se = base;
        for (size_t k = 0; k < 3 * np; ++k) {
          std::vector<double> mean_levels = level_sums[ci][k];
          for (double& l : mean_levels) l /= seeds;
          t.pred[k] = extrapolate(Ext(e), mean_levels);
        }
        const Row r = summarise(t, ref, base);
        std::printf("| %s | %u | %s, expected levels | %.2f | %.3f | %.2f | %.2f |\n", name.c_str(), n, kExtNames[e],
                    r.cost, r.aggregate, r.p50, r.p99);
      }
      std::fflush(stdout);
      if (!replicates) continue;
      for (uint32_t k : {2u, 4u}) {
        Tally t(3 * np);
        for (int seed = 0; seed < seeds; ++seed) {
          RenderOptions o;
          o.spp = n;
          o.seed = 7 + uint64_t(seed);
          o.replicates = k;
          o.variance = true;
          const RenderResult res = render(s, o);
          const char* names[3] = {"variance.R", "variance.G", "variance.B"};
          for (size_t i = 0; i < np; ++i)
            for (size_t c = 0; c < 3; ++c) {
              const double d = double(res.image.rgb[3 * i + c]) - ref.rgb[3 * i + c];
              t.se[3 * i + c] += d * d / seeds;
              t.pred[3 * i + c] += double(res.image.extra.at(names[c])[i]) / seeds;
            }
        }
        const Row r = summarise(t, ref, base);
        std::printf("| %s | %u | %u replicates of %u | %.2f | %.3f | %.2f | %.2f |\n", name.c_str(), n, k, n / k,
                    r.cost, r.aggregate, r.p50, r.p99);
      }
      std::fflush(stdout);
    }
  }
}
