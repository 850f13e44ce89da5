#include "core/render.h"

#include "core/path_integrator.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <mutex>

namespace tessera {

PixelSampler pixel_sampler(uint64_t seed, int px, int row, uint32_t s, uint32_t replicates) {
  if (replicates <= 1) return PixelSampler(seed, px, row, s);
  // Replicate r = s mod K is its own scrambled sequence: the seed is mixed with r, the index is s / K.
  const uint64_t r = s % replicates;
  return PixelSampler(seed ^ ((r + 1) * 0x9E3779B97F4A7C15ULL), px, row, s / replicates);
}

namespace {

// Adds samples [acc.count(), end) of pixel (px, row) to acc, in order.
void add_samples(const Scene& scene, int px, int row, uint64_t seed, uint32_t end, uint32_t replicates,
                 PixelAccumulator& acc, RayCounters& counters) {
  for (uint32_t s = acc.count(); s < end; ++s) {
    PixelSampler sampler = pixel_sampler(seed, px, row, s, replicates);
    const Ray r = scene.camera.generate_pixel(px, row, sampler.next_2d(), scene.width, scene.height);
    acc.add(trace_sample(scene, r, sampler, counters));
  }
}

}  // namespace

PixelEstimate render_pixel(const Scene& scene, int px, int row, uint64_t seed, uint32_t spp, RayCounters& counters,
                           uint32_t replicates) {
  // Double accumulators in sample order: the sum does not depend on anything but the pixel and its samples.
  PixelAccumulator acc(replicates);
  add_samples(scene, px, row, seed, spp, replicates, acc, counters);
  return acc.estimate();
}

PixelEstimate render_pixel_adaptive(const Scene& scene, int px, int row, uint64_t seed, const AdaptiveOptions& opt,
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
  return acc.estimate();
}

RenderResult render(const Scene& scene, const RenderOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  RenderResult res;
  res.window = opt.window.empty() ? PixelWindow{0, 0, scene.width, scene.height} : opt.window;
  const PixelWindow w = res.window;
  const uint32_t spp = opt.spp ? opt.spp : scene.settings.spp;
  const bool adaptive = opt.target_error > 0.f;
  const AdaptiveOptions ao{opt.target_error, opt.min_spp, opt.max_spp, opt.error_floor, opt.replicates};
  res.image = Image::make(w.width(), w.height());
  if (opt.variance) {
    for (const char* c : {"variance.R", "variance.G", "variance.B", "samples"})
      res.image.extra[c].assign(size_t(w.width()) * size_t(w.height()), 0.f);
  }
  // Channel pointers taken once: threads write disjoint pixels and never touch the map itself.
  float* var_ch[4] = {nullptr, nullptr, nullptr, nullptr};
  if (opt.variance) {
    int k = 0;
    for (const char* c : {"variance.R", "variance.G", "variance.B", "samples"}) var_ch[k++] = res.image.extra[c].data();
  }
  const int ts = std::max(1, opt.tile_size);
  const int tx = (w.width() + ts - 1) / ts, ty = (w.height() + ts - 1) / ts;
  const int ntiles = tx * ty;
  tbb::enumerable_thread_specific<RayCounters> counters;
  std::mutex progress_mutex;
  std::atomic<int> done{0};
  std::atomic<uint64_t> rays_done{0};
  std::atomic<bool> cancelled{false};

  tbb::parallel_for(tbb::blocked_range<int>(0, ntiles, 1), [&](const tbb::blocked_range<int>& range) {
    RayCounters& c = counters.local();
    for (int t = range.begin(); t != range.end(); ++t) {
      if (opt.cancel && opt.cancel->load(std::memory_order_relaxed)) {
        cancelled = true;
        return;
      }
      const uint64_t before = c.rays;
      const int x0 = w.x0 + (t % tx) * ts, y0 = w.y0 + (t / tx) * ts;
      const int x1 = std::min(x0 + ts, w.x1), y1 = std::min(y0 + ts, w.y1);
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const PixelEstimate e = adaptive ? render_pixel_adaptive(scene, x, y, opt.seed, ao, c)
                                           : render_pixel(scene, x, y, opt.seed, spp, c, opt.replicates);
          const int lx = x - w.x0, ly = y - w.y0;
          res.image.set(lx, ly, e.mean);
          if (opt.variance) {
            const size_t i = size_t(ly) * size_t(w.width()) + size_t(lx);
            var_ch[0][i] = e.var_mean.x;
            var_ch[1][i] = e.var_mean.y;
            var_ch[2][i] = e.var_mean.z;
            var_ch[3][i] = float(e.spp);
          }
        }
      const int d = ++done;
      const uint64_t rays = rays_done += c.rays - before;
      if (opt.progress) {
        std::lock_guard<std::mutex> lock(progress_mutex);
        opt.progress(RenderProgress{d, ntiles, rays,
                                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()});
      }
    }
  });
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
