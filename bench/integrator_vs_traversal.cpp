// The integrator against the traversal limit: for each scene, the end-to-end rate of a real
// render (rays/s on one thread and on all threads) beside the rate of traversal alone on the rays that render
// traced, recorded through RenderOptions::recorder and replayed through Bvh::intersect / Bvh::occluded (the same
// query each ray had). The ratio end-to-end / traversal-only is the share of a render's time spent in traversal;
// the rest is shading, sampling, light selection, texture lookups, film accumulation and bookkeeping.
//
//   ./build/bench/integrator_vs_traversal [--scenes a,b,...] [--spp N] [--scale F] [--repeats N] [--keep K]
//                                         [--burst B] [--quick]
//
// The recording render runs on one thread and keeps one burst of B consecutive rays in every K (so the replay keeps
// the render's order and coherence within a burst). The timed renders run without a recorder. Every repetition
// measures the four rates in a rotated order, so that noise from other processes spreads over them; each figure is
// the best of the repetitions. One-thread figures are per second of that thread's CPU time, all-thread ones per
// second of wall time.
#include "bench/run_environment.h"
#include "core/geometry/bvh.h"
#include "core/render/ray_recorder.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using namespace tessera;
using Clock = std::chrono::steady_clock;
using tessera::bench::cpu_model;
using tessera::bench::load_average;

namespace {

// ---------------------------------------------------------------------------------------------------------------
// Timing (the run's machine, commit and load come from bench/run_environment.h).

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// CPU time of the calling thread: what a 1-thread measurement costs, whatever else the machine runs (a task_arena of
// one runs its work on the thread that calls execute()).
double thread_cpu_seconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// ---------------------------------------------------------------------------------------------------------------
// Recording.

struct RecordedRay {
  Ray ray;
  RayKind kind;
};

// Keeps one burst of `burst` consecutive rays in every `keep` bursts of each thread's stream, and counts all of them
// by kind.
class BurstRecorder final : public RayRecorder {
 public:
  BurstRecorder(size_t burst, size_t keep) : burst_(burst), keep_(keep) {}

  void record(RayKind kind, const Ray& r) override {
    Local& l = local_.local();
    ++l.seen[size_t(kind)];
    if ((l.calls++ / burst_) % keep_ == 0) l.rays.push_back({r, kind});
  }

  // The kept rays, thread by thread, each thread's in the order traced; and every call counted by kind.
  std::vector<RecordedRay> take(std::array<uint64_t, kRayKinds>* seen) {
    std::vector<RecordedRay> all;
    seen->fill(0);
    for (Local& l : local_) {
      all.insert(all.end(), l.rays.begin(), l.rays.end());
      for (int k = 0; k < kRayKinds; ++k) (*seen)[size_t(k)] += l.seen[size_t(k)];
    }
    return all;
  }

 private:
  struct Local {
    uint64_t calls = 0;
    std::array<uint64_t, kRayKinds> seen{};
    std::vector<RecordedRay> rays;
  };
  size_t burst_, keep_;
  tbb::enumerable_thread_specific<Local> local_;
};

// ---------------------------------------------------------------------------------------------------------------
// Replay: each ray through the query it had, in order. Returns a checksum so the loop stays observable.

double replay(const Bvh& bvh, const RecordedRay* rays, size_t n) {
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const RecordedRay& rr = rays[i];
    if (traced_as_any_hit(rr.kind)) {
      sum += bvh.occluded(rr.ray) ? 1.0 : 0.0;
    } else if (const auto h = bvh.intersect(rr.ray)) {
      sum += double(h->t);
    }
  }
  return sum;
}

// The same replay with each ray waiting for the answer before it, as in a render, where a shadow or bounce ray
// leaves from the hit just found: the origin gets a zero made from the previous answer (a hit's t is finite, so
// t * 0 is 0; the compiler cannot fold it without knowing that), which the CPU cannot have before that answer.
// Independent rays let it start a ray's traversal while the one before still runs.
double replay_chained(const Bvh& bvh, const RecordedRay* rays, size_t n) {
  double sum = 0.0;
  float zero = 0.f;
  for (size_t i = 0; i < n; ++i) {
    Ray r = rays[i].ray;
    r.o.x += zero;
    float v = 0.f;
    if (traced_as_any_hit(rays[i].kind)) v = bvh.occluded(r) ? 1.f : 0.f;
    else if (const auto h = bvh.intersect(r)) v = h->t;
    sum += double(v);
    zero = v * 0.f;
  }
  return sum;
}

// Replay on all threads: bursts of consecutive rays handed out one at a time, as a render hands out tiles.
double replay_parallel(const Bvh& bvh, const std::vector<RecordedRay>& rays, size_t burst) {
  const size_t chunks = (rays.size() + burst - 1) / burst;
  tbb::enumerable_thread_specific<double> sums(0.0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c) {
      const size_t b = c * burst, e = std::min(rays.size(), b + burst);
      sums.local() += replay(bvh, rays.data() + b, e - b);
    }
  });
  double s = 0.0;
  for (double v : sums) s += v;
  return s;
}

std::string pixel_hash(const Image& img) {
  Sha256 h;
  h.update({reinterpret_cast<const uint8_t*>(img.rgb.data()), img.rgb.size() * sizeof(float)});
  return h.hex().substr(0, 16);
}

// ---------------------------------------------------------------------------------------------------------------

struct Args {
  std::vector<std::string> scenes = {"cbox_no_light", "cbox_no_light_refraction", "cbox_area_light", "cbox_env_light",
                                     "sky_sun"};
  uint32_t spp = 16;
  double scale = 1.0;
  int repeats = 3;
  size_t keep = 8;
  size_t burst = 4096;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "integrator_vs_traversal: %s\nusage: integrator_vs_traversal [--scenes a,b,...] [--spp N] [--scale F] "
               "[--repeats N] [--keep K] [--burst B] [--quick]\n",
               why);
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + k).c_str());
      return argv[++i];
    };
    if (k == "--scenes") {
      a.scenes.clear();
      std::stringstream ss(value());
      for (std::string s; std::getline(ss, s, ',');)
        if (!s.empty()) a.scenes.push_back(s);
    } else if (k == "--spp") {
      a.spp = uint32_t(std::stoul(value()));
    } else if (k == "--scale") {
      a.scale = std::stod(value());
    } else if (k == "--repeats") {
      a.repeats = std::stoi(value());
    } else if (k == "--keep") {
      a.keep = std::stoul(value());
    } else if (k == "--burst") {
      a.burst = std::stoul(value());
    } else if (k == "--quick") {
      a.scale = 0.25;
      a.spp = 4;
      a.repeats = 1;
    } else {
      usage(("unknown argument " + k).c_str());
    }
  }
  if (a.scenes.empty() || a.spp == 0 || !(a.scale > 0.0 && a.scale <= 1.0) || a.repeats < 1 || a.keep < 1 || a.burst < 1)
    usage("bad argument value");
  return a;
}

struct Row {
  std::string scene;
  int width = 0, height = 0;
  uint32_t spp = 0;
  double rays_per_sample = 0;
  std::array<uint64_t, kRayKinds> seen{};
  size_t kept = 0;
  double e2e1 = 0, trav1 = 0, e2eN = 0, travN = 0;  // best rates, rays/s
  double chained1 = 0;                               // best single-thread rate of the chained replay
  std::array<double, 2> trav_by_query{};             // closest, any hit: best single-thread rates
  std::string hash;
  bool recorder_changes_nothing = false;
};

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  const int nthreads = tbb::info::default_concurrency();
  const std::string load_before = load_average();
  const auto t_start = Clock::now();
  std::printf("integrator_vs_traversal: end-to-end render rate against traversal alone on the render's own rays\n");
  std::printf("commit:   %s\n", tessera::bench::commit_description(TESSERA_SOURCE_DIR, TESSERA_CONFIGURE_COMMIT).c_str());
  std::printf("machine:  %s, nproc %u, TBB default concurrency %d\n", cpu_model().c_str(),
              std::thread::hardware_concurrency(), nthreads);
  std::printf("build:    %s, flags \"%s\" -ffp-contract=off, TESSERA_NATIVE=%s\n", TESSERA_BUILD_TYPE,
              TESSERA_BUILD_FLAGS, TESSERA_NATIVE_BUILD ? "ON" : "OFF");
  std::printf("settings: %u spp (at most the scene's), resolution x%g, seed 0, best of %d; recording on 1 thread keeps "
              "one burst of %zu rays in %zu\n",
              args.spp, args.scale, args.repeats, args.burst, args.keep);
  std::printf("load:     %s (1, 5, 15 min) at the start\n\n", load_before.c_str());
  std::fflush(stdout);

  std::vector<Row> rows;
  for (const std::string& name : args.scenes) {
    LoadedScene loaded = load_scene_file(fs::path(TESSERA_SOURCE_DIR) / "scenes" / (name + ".json"));
    Scene& scene = loaded.scene;
    if (args.scale < 1.0) {
      scene.width = std::max(1, int(scene.width * args.scale));
      scene.height = std::max(1, int(scene.height * args.scale));
    }
    Row row;
    row.scene = name;
    row.width = scene.width;
    row.height = scene.height;
    row.spp = std::min(args.spp, scene.settings.spp);
    RenderOptions ro;
    ro.spp = row.spp;

    // The recording render, on one thread so the kept sample is the same in every run.
    BurstRecorder recorder(args.burst, args.keep);
    RenderOptions rec_opt = ro;
    rec_opt.recorder = &recorder;
    tbb::task_arena one(1);
    RenderResult recorded;
    one.execute([&] { recorded = render(scene, rec_opt); });
    const std::vector<RecordedRay> rays = recorder.take(&row.seen);
    row.kept = rays.size();
    uint64_t seen_total = 0;
    for (uint64_t s : row.seen) seen_total += s;
    if (seen_total != recorded.counters.rays) {
      std::fprintf(stderr, "integrator_vs_traversal: %s: the recorder saw %llu rays, the render counted %llu\n",
                   name.c_str(), (unsigned long long)seen_total, (unsigned long long)recorded.counters.rays);
      return 1;
    }
    row.rays_per_sample = double(recorded.counters.rays) / double(recorded.counters.camera);
    std::vector<RecordedRay> by_query[2];
    for (const RecordedRay& r : rays) by_query[traced_as_any_hit(r.kind) ? 1 : 0].push_back(r);

    double sink = 0.0;
    std::string hash1, hashN;
    for (int rep = 0; rep < args.repeats; ++rep) {
      for (int step = 0; step < 4; ++step) {
        switch ((step + rep) % 4) {
          case 0: {
            RenderResult res;
            double cpu = 0.0;
            one.execute([&] {
              const double c0 = thread_cpu_seconds();
              res = render(scene, ro);
              cpu = thread_cpu_seconds() - c0;
            });
            row.e2e1 = std::max(row.e2e1, double(res.counters.rays) / cpu);
            hash1 = pixel_hash(res.image);
            break;
          }
          case 1: {
            one.execute([&] {
              double c0 = thread_cpu_seconds();
              sink += replay(scene.bvh, rays.data(), rays.size());
              row.trav1 = std::max(row.trav1, double(rays.size()) / (thread_cpu_seconds() - c0));
              c0 = thread_cpu_seconds();
              sink += replay_chained(scene.bvh, rays.data(), rays.size());
              row.chained1 = std::max(row.chained1, double(rays.size()) / (thread_cpu_seconds() - c0));
              for (int q = 0; q < 2; ++q) {
                if (by_query[q].empty()) continue;
                c0 = thread_cpu_seconds();
                sink += replay(scene.bvh, by_query[q].data(), by_query[q].size());
                row.trav_by_query[size_t(q)] =
                    std::max(row.trav_by_query[size_t(q)], double(by_query[q].size()) / (thread_cpu_seconds() - c0));
              }
            });
            break;
          }
          case 2: {
            const RenderResult res = render(scene, ro);
            row.e2eN = std::max(row.e2eN, double(res.counters.rays) / res.seconds);
            hashN = pixel_hash(res.image);
            break;
          }
          case 3: {
            const auto t = Clock::now();
            sink += replay_parallel(scene.bvh, rays, args.burst);
            row.travN = std::max(row.travN, double(rays.size()) / seconds_since(t));
            break;
          }
        }
      }
    }
    row.hash = hash1;
    row.recorder_changes_nothing = hash1 == pixel_hash(recorded.image) && hash1 == hashN;
    if (!row.recorder_changes_nothing) {
      std::fprintf(stderr, "integrator_vs_traversal: %s: pixels differ between the recorded, 1-thread and %d-thread "
                   "renders\n", name.c_str(), nthreads);
      return 1;
    }
    std::printf("  %s done (checksum %g)\n", name.c_str(), sink);
    std::fflush(stdout);
    rows.push_back(row);
  }

  std::printf("\nMrays/s: 1-thread columns per second of the thread's CPU time (so other processes on the machine "
              "do not count), %d-thread columns per second of wall time\n", nthreads);
  std::printf("ratio = end-to-end / traversal-only (the share of a render's time spent traversing; goal >= "
              "0.80); other ns/ray = the time per ray outside traversal, 1/end-to-end - 1/traversal-only\n\n");
  std::printf("| scene | size, spp | rays/sample | mix camera/specular/bounce/shadow %% | 1 thread: end-to-end | "
              "traversal-only | ratio | other ns/ray | %d threads: end-to-end | traversal-only | ratio |\n",
              nthreads);
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    uint64_t total = 0;
    for (uint64_t s : r.seen) total += s;
    std::printf("| %s | %dx%d, %u | %.2f | %.0f/%.0f/%.0f/%.0f | %.2f | %.2f | %.2f | %.0f | %.2f | %.2f | %.2f |\n",
                r.scene.c_str(), r.width, r.height, r.spp, r.rays_per_sample, 100.0 * double(r.seen[0]) / double(total),
                100.0 * double(r.seen[1]) / double(total), 100.0 * double(r.seen[2]) / double(total),
                100.0 * double(r.seen[3]) / double(total), r.e2e1 * 1e-6, r.trav1 * 1e-6, r.e2e1 / r.trav1,
                1e9 * (1.0 / r.e2e1 - 1.0 / r.trav1), r.e2eN * 1e-6, r.travN * 1e-6, r.e2eN / r.travN);
  }
  std::printf("\nTraversal-only by query (1 thread, Mrays/s), rays replayed, and the pixels' SHA-256 (RGB, first 16 hex "
              "digits; identical with and without the recorder and on 1 and %d threads):\n\n", nthreads);
  std::printf("| scene | closest hit | any hit | rays replayed | pixels |\n|---|---|---|---|---|\n");
  for (const Row& r : rows)
    std::printf("| %s | %.2f | %.2f | %zu | %s |\n", r.scene.c_str(), r.trav_by_query[0] * 1e-6,
                r.trav_by_query[1] * 1e-6, r.kept, r.hash.c_str());
  std::printf("\nTraversal-only with each ray waiting for the answer before it (1 thread, Mrays/s; see replay_chained), "
              "and the render's end-to-end rate against it:\n\n");
  std::printf("| scene | traversal-only, independent rays | chained rays | independent / chained | end-to-end / chained "
              "|\n|---|---|---|---|---|\n");
  for (const Row& r : rows)
    std::printf("| %s | %.2f | %.2f | %.2f | %.2f |\n", r.scene.c_str(), r.trav1 * 1e-6, r.chained1 * 1e-6,
                r.trav1 / r.chained1, r.e2e1 / r.chained1);
  std::printf("\nload:     %s (1, 5, 15 min) at the end; %.0f s in all\n", load_average().c_str(),
              seconds_since(t_start));
  return 0;
}
