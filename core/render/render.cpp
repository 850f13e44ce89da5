#include "core/render/render.h"

#include "core/render/layer_film.h"
#include "core/render/path_integrator.h"
#include "core/util/zeroed_buffer.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

namespace tessera {

namespace {

// The seed of replicate r of K >= 2: each replicate is its own scrambled sequence.
uint64_t replicate_seed(uint64_t seed, uint32_t r) { return seed ^ ((uint64_t(r) + 1) * 0x9E3779B97F4A7C15ULL); }

}  // namespace

PixelSampler pixel_sampler(uint64_t seed, int px, int row, uint32_t s, uint32_t replicates) {
  if (replicates <= 1) return PixelSampler(seed, px, row, s);
  // Replicate r = s mod K is its own scrambled sequence: the seed is mixed with r, the index is s / K.
  return PixelSampler(replicate_seed(seed, s % replicates), px, row, s / replicates);
}

namespace {

// Adds samples [acc.count(), end) of pixel (px, row) to acc, in order, sampler(s) giving sample s's stream. Two
// samples at a time: both camera rays are traced before either sample is shaded, and the path tracer goes on with the
// two paths side by side (trace_path_pair), so the CPU overlaps two independent chains of work, which one sample at a
// time cannot give it: each ray of a sample waits for the answer before it (`integrator_vs_traversal`'s chained
// replay). Each sample's arithmetic and the order of the sums are those of one sample at a time, so no pixel changes.
template <class Sampler>
void add_samples_paired(const Scene& scene, int px, int row, uint32_t end, const Sampler& sampler, PixelAccumulator& acc,
                        RayCounters& counters) {
  const auto camera_ray = [&](PixelSampler& p) {
    return scene.camera.generate_pixel(px, row, p.next_2d(), scene.width, scene.height);
  };
  uint32_t s = acc.count();
  for (; s + 2 <= end; s += 2) {
    PixelSampler a = sampler(s), b = sampler(s + 1);
    const Ray ra = camera_ray(a), rb = camera_ray(b);
    const std::optional<Hit> ha = trace_closest(scene, ra, RayKind::kCamera, counters);
    const std::optional<Hit> hb = trace_closest(scene, rb, RayKind::kCamera, counters);
    const std::array<Vec3, 2> L = trace_sample_pair(scene, ra, ha, a, rb, hb, b, counters);
    acc.add(L[0]);
    acc.add(L[1]);
  }
  if (s < end) {
    PixelSampler a = sampler(s);
    acc.add(trace_sample(scene, camera_ray(a), a, counters));
  }
}

// Adds samples [acc.count(), end) of pixel (px, row) to acc, in order: the samplers of pixel_sampler(), with the
// pixel's keys hashed once (and, with one replicate, its dimensions' seeds once: PixelSeeds).
void add_samples(const Scene& scene, int px, int row, uint64_t seed, uint32_t end, uint32_t replicates,
                 PixelAccumulator& acc, RayCounters& counters) {
  if (replicates <= 1) {
    PixelSeeds seeds(PixelSampler::pixel_key(seed, px, row));
    add_samples_paired(scene, px, row, end, [&seeds](uint32_t s) { return PixelSampler(seeds, s); }, acc, counters);
    return;
  }
  if (replicates > kMaxReplicates) {
    add_samples_paired(
        scene, px, row, end, [&](uint32_t s) { return pixel_sampler(seed, px, row, s, replicates); }, acc, counters);
    return;
  }
  uint32_t keys[kMaxReplicates];
  const uint32_t k = replicates;
  for (uint32_t r = 0; r < k; ++r) keys[r] = PixelSampler::pixel_key(replicate_seed(seed, r), px, row);
  add_samples_paired(scene, px, row, end, [&](uint32_t s) { return PixelSampler(keys[s % k], s / k); }, acc, counters);
}

}  // namespace

PixelEstimate render_pixel(const Scene& scene, int px, int row, uint64_t seed, uint32_t spp, RayCounters& counters,
                           uint32_t replicates) {
  // Double accumulators in sample order: the sum does not depend on anything but the pixel and its samples.
  PixelAccumulator acc(replicates);
  add_samples(scene, px, row, seed, spp, replicates, acc, counters);
  return acc.estimate();
}

namespace {

// Pixel (px, row) sampled adaptively from scratch (rounds as render_pixel_adaptive describes).
PixelAccumulator sample_adaptive(const Scene& scene, int px, int row, uint64_t seed, const AdaptiveOptions& opt,
                                 RayCounters& counters) {
  const uint32_t k = std::clamp<uint32_t>(opt.replicates, 1, kMaxReplicates);
  // Rounds are multiples of the replicate count (and of 2, so a variance exists).
  const uint32_t unit = std::max<uint32_t>(k, 2);
  const uint32_t max_spp = std::max(unit, opt.max_spp / unit * unit);
  const uint32_t min_spp = std::min(max_spp, std::max(unit, (opt.min_spp + unit - 1) / unit * unit));
  PixelAccumulator acc(k);
  for (uint32_t n = min_spp;; n = std::min(max_spp, next_round(n, max_spp) / unit * unit)) {
    add_samples(scene, px, row, seed, n, k, acc, counters);
    if (n >= max_spp || acc.relative_error(opt.error_floor) <= opt.target_error) break;
  }
  return acc;
}

const char* const kVarianceChannels[4] = {"variance.R", "variance.G", "variance.B", "samples"};

// Refuses a previous render that cannot be continued into this one (see RenderOptions::previous).
void check_previous(const StoredRender& p, const RenderOptions& opt, bool variance, const PixelWindow& w, uint32_t spp,
                    uint32_t k) {
  const auto refuse = [](const std::string& why) { throw std::invalid_argument("cannot continue the render: " + why); };
  const size_t n = size_t(w.width()) * size_t(w.height());
  if (p.image.width != w.width() || p.image.height != w.height() || p.state.samples.size() != n)
    refuse("its size differs from the window's");
  if (p.state.replicates != k) refuse("it has another replicate count");
  if (p.state.exact() && p.state.sums.size() != n * PixelAccumulator::state_size(k))
    refuse("its accumulators do not cover the window");
  if (opt.keep_state && !p.state.exact()) refuse("its exact accumulators were not kept");
  if (variance)
    for (const char* c : kVarianceChannels)
      if (!p.image.extra.count(c) || p.image.extra.at(c).size() != n) refuse(std::string("it has no ") + c + " channel");
  if (opt.target_error > 0.f) return;  // adaptive: pixels with samples are kept as they are
  for (const uint32_t had : p.state.samples) {
    if (had > spp) refuse("a pixel has " + std::to_string(had) + " samples, more than " + std::to_string(spp));
    if (had != 0 && had != spp && !p.state.exact())
      refuse("a pixel has " + std::to_string(had) + " of " + std::to_string(spp) +
             " samples and no exact accumulator to continue from");
  }
}

}  // namespace

PixelEstimate render_pixel_adaptive(const Scene& scene, int px, int row, uint64_t seed, const AdaptiveOptions& opt,
                                    RayCounters& counters) {
  return sample_adaptive(scene, px, row, seed, opt, counters).estimate();
}

RenderResult render(const Scene& scene, const RenderOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  RenderResult res;
  res.window = opt.window.empty() ? PixelWindow{0, 0, scene.width, scene.height} : opt.window;
  const PixelWindow w = res.window;
  const uint32_t spp = opt.spp ? opt.spp : scene.settings.spp;
  const bool adaptive = opt.target_error > 0.f;
  const AdaptiveOptions ao{opt.target_error, opt.min_spp, opt.max_spp, opt.error_floor, opt.replicates};
  const uint32_t k = std::clamp<uint32_t>(opt.replicates, 1, kMaxReplicates);
  const StoredRender* prev = opt.previous;
  const bool variance = opt.variance || opt.layers.has(Layer::kVariance);
  if (prev) check_previous(*prev, opt, variance, w, spp, k);
  const size_t npix = size_t(w.width()) * size_t(w.height());
  res.image = Image::make(w.width(), w.height());
  res.state.replicates = k;
  assign_zeroed(res.state.samples, npix);
  if (opt.keep_state) assign_zeroed(res.state.sums, npix * PixelAccumulator::state_size(k));
  // Channel pointers taken once: threads write disjoint pixels and never touch the maps themselves.
  float* var_ch[4] = {nullptr, nullptr, nullptr, nullptr};
  const float* prev_var_ch[4] = {nullptr, nullptr, nullptr, nullptr};
  if (variance) {
    for (int c = 0; c < 4; ++c) {
      std::vector<float>& ch = res.image.extra[kVarianceChannels[c]];
      assign_zeroed(ch, npix);
      var_ch[c] = ch.data();
      if (prev) prev_var_ch[c] = prev->image.extra.at(kVarianceChannels[c]).data();
    }
  }
  const LayerFilm layers(scene, opt.layers, res.image);
  tbb::enumerable_thread_specific<LayerScratch> layer_scratch;
  // The first-hit layers of a pixel with n samples (recomputed from its camera rays, even for a copied pixel).
  const auto store_layers = [&](size_t i, int lx, int ly, uint32_t n) {
    if (layers.active()) layers.render_pixel(w.x0 + lx, w.y0 + ly, opt.seed, n, k, i, layer_scratch.local());
  };
  // A pixel's result from its accumulator.
  const auto store = [&](size_t i, int lx, int ly, const PixelAccumulator& acc) {
    const PixelEstimate e = acc.estimate();
    res.image.set(lx, ly, e.mean);
    store_layers(i, lx, ly, acc.count());
    if (variance) {
      for (int c = 0; c < 3; ++c) var_ch[c][i] = e.var_mean[c];
      var_ch[3][i] = float(e.spp);
    }
    if (opt.keep_state) res.state.set(i, acc);
    else res.state.samples[i] = acc.count();
  };
  // A pixel copied as the previous render wrote it (its colour was written as float: see the CLI's partial files).
  const auto copy_previous = [&](size_t i, int lx, int ly) {
    res.image.set(lx, ly, prev->image.at(lx, ly));
    store_layers(i, lx, ly, prev->state.samples[i]);
    if (variance)
      for (int c = 0; c < 4; ++c) var_ch[c][i] = prev_var_ch[c][i];
    res.state.samples[i] = prev->state.samples[i];
  };
  const int ts = std::max(1, opt.tile_size);
  const int tx = (w.width() + ts - 1) / ts, ty = (w.height() + ts - 1) / ts;
  const int ntiles = tx * ty;
  tbb::enumerable_thread_specific<RayCounters> counters;
  std::mutex progress_mutex;
  std::atomic<int> done{0}, started{0};
  std::atomic<uint64_t> rays_done{0};
  std::atomic<bool> cancelled{false};

  // Threads the render can use: one task each, taking the next free tile in row-major order until none is left,
  // so that rows of tiles finish roughly from the top down (the order RenderOptions::rows_final tells them in).
  res.threads = int(std::min<size_t>(size_t(tbb::this_task_arena::max_concurrency()),
                                      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
  std::atomic<int> next_tile{0};
  // Per row of tiles: its tiles not yet final (a tile stopped by cancel or the budget never is).
  std::unique_ptr<std::atomic<int>[]> row_tiles_left;
  if (opt.rows_final) {
    row_tiles_left = std::make_unique<std::atomic<int>[]>(size_t(ty));
    for (int r = 0; r < ty; ++r) row_tiles_left[size_t(r)].store(tx, std::memory_order_relaxed);
  }
  // Rows of tiles finished and not yet looked at by the thread telling rows_final; that thread is the one that
  // raised it from 0, and it looks again until it brings it back to 0, so no finished row waits for a later one.
  std::atomic<int> row_requests{0};
  int rows_told = 0;  // rows of tiles told to rows_final (only the telling thread touches it)
  const auto tell_rows = [&] {
    if (row_requests.fetch_add(1, std::memory_order_acq_rel) != 0) return;
    do {
      const int first = rows_told;
      while (rows_told < ty && row_tiles_left[size_t(rows_told)].load(std::memory_order_acquire) == 0) ++rows_told;
      if (rows_told > first) opt.rows_final(res.image, res.state, first * ts, std::min(rows_told * ts, w.height()));
    } while (row_requests.fetch_sub(1, std::memory_order_acq_rel) != 1);
  };

  tbb::enumerable_thread_specific<double> busy_seconds(0.0);  // per thread: time spent on tiles
  const auto t_parallel = std::chrono::steady_clock::now();
  const auto render_tiles = [&] {
    RayCounters& c = counters.local();
    c.recorder = opt.recorder;
    const auto t_start = std::chrono::steady_clock::now();
    for (int t = next_tile.fetch_add(1, std::memory_order_relaxed); t < ntiles;
         t = next_tile.fetch_add(1, std::memory_order_relaxed)) {
      const bool over_budget = opt.tile_budget > 0 && started.fetch_add(1) >= opt.tile_budget;
      const uint64_t before = c.rays;
      const int x0 = w.x0 + (t % tx) * ts, y0 = w.y0 + (t / tx) * ts;
      const int x1 = std::min(x0 + ts, w.x1), y1 = std::min(y0 + ts, w.y1);
      bool tile_stopped = false;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const int lx = x - w.x0, ly = y - w.y0;
          const size_t i = size_t(ly) * size_t(w.width()) + size_t(lx);
          const bool stop = over_budget || (opt.cancel && opt.cancel->load(std::memory_order_relaxed));
          if (stop) {
            cancelled.store(true, std::memory_order_relaxed);
            tile_stopped = true;
          }
          const uint32_t had = prev ? prev->state.samples[i] : 0U;
          if (had > 0 && prev->state.exact()) {
            PixelAccumulator acc = prev->state.pixel(i);
            if (!stop && !adaptive) add_samples(scene, x, y, opt.seed, spp, k, acc, c);
            store(i, lx, ly, acc);
          } else if (had > 0) {
            copy_previous(i, lx, ly);
          } else if (!stop) {
            PixelAccumulator acc(k);
            if (adaptive) acc = sample_adaptive(scene, x, y, opt.seed, ao, c);
            else add_samples(scene, x, y, opt.seed, spp, k, acc, c);
            store(i, lx, ly, acc);
          }
        }
      if (opt.rows_final && !tile_stopped &&
          row_tiles_left[size_t(t / tx)].fetch_sub(1, std::memory_order_acq_rel) == 1)
        tell_rows();
      const int d = ++done;
      const uint64_t rays = rays_done += c.rays - before;
      if (opt.progress) {
        std::lock_guard<std::mutex> lock(progress_mutex);
        opt.progress(RenderProgress{d, ntiles, rays,
                                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()});
      }
    }
    busy_seconds.local() += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  };
  tbb::parallel_for(
      tbb::blocked_range<int>(0, std::max(1, std::min(res.threads, ntiles)), 1),
      [&](const tbb::blocked_range<int>& slots) {
        for (int s = slots.begin(); s != slots.end(); ++s) render_tiles();
      },
      tbb::simple_partitioner());
  res.parallel_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_parallel).count();
  double busy = 0.0;
  for (const double b : busy_seconds) busy += b;
  res.idle_thread_seconds = std::max(0.0, double(res.threads) * res.parallel_seconds - busy);
  for (const RayCounters& c : counters) {
    res.counters.camera += c.camera;
    res.counters.rays += c.rays;
    res.counters.nonfinite += c.nonfinite;
  }
  res.cancelled = cancelled;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace tessera
