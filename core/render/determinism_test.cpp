// Pixels are a pure function of (scene, spp, seed, pixel): the same bits for any thread count, and the same bits as
// the golden checksums kept in tests/golden/renders.sha256, so that a compiler, a flag set (-O0, -march=native), a
// sanitizer build or a CPU that changes one pixel fails the suite. A deliberate change of the estimator updates
// the goldens in the same commit, with the reason (run core_tests with TESSERA_UPDATE_GOLDEN=1 to rewrite the file).
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

namespace tessera {
namespace {

namespace fs = std::filesystem;

const fs::path kScenes = fs::path(TESSERA_SOURCE_DIR) / "scenes";
const fs::path kGolden = fs::path(TESSERA_SOURCE_DIR) / "tests/golden/renders.sha256";

// A small render: a 96x64 window around the image's centre at 8 samples per pixel in 8-pixel tiles, variance channels
// included (they go through more of the arithmetic than the mean).
struct Case {
  std::string name;   // the golden's key
  std::string scene;  // in scenes/
  uint32_t spp;
  uint32_t replicates;
  LayerSet layers{};  // output layers beside the colour
};

const std::vector<Case> kCases = {{"cbox_area_light", "cbox_area_light.json", 8, 1},
                                  {"cbox_no_light_refraction", "cbox_no_light_refraction.json", 8, 1},
                                  {"cbox_env_light", "cbox_env_light.json", 8, 2},
                                  {"sky_sun", "sky_sun.json", 8, 1},
                                  // The path tracer: diffuse interreflection, glass and rough metal.
                                  {"cbox_gi", "cbox_gi.json", 8, 1},
                                  {"cbox_glass", "cbox_glass.json", 8, 2},
                                  // Every output layer, through refraction and glass.
                                  {"cbox_no_light_refraction_layers", "cbox_no_light_refraction.json", 8, 1,
                                   LayerSet::from_bits(~0u)},
                                  {"cbox_glass_layers", "cbox_glass.json", 8, 2, LayerSet::from_bits(~0u)}};

const Scene& scene_of(const std::string& file) {
  static std::map<std::string, LoadedScene> cache;
  static std::mutex mu;
  std::lock_guard lock(mu);
  auto it = cache.find(file);
  if (it == cache.end()) it = cache.emplace(file, load_scene_file(kScenes / file)).first;
  return it->second.scene;
}

// SHA-256 of the pixels: each channel's name and its float32 values' bytes (little-endian, as in memory on x86-64 and
// as stored in the EXR), RGB first and the extra channels in name order.
std::string pixel_hash(const Image& img) {
  Sha256 h;
  auto feed = [&](const std::string& name, const std::vector<float>& v) {
    h.update(name);
    h.update({reinterpret_cast<const uint8_t*>(v.data()), v.size() * sizeof(float)});
  };
  feed("RGB", img.rgb);
  for (const auto& [name, ch] : img.extra) feed(name, ch);
  return h.hex();
}

struct Rendered {
  std::string hash;
  size_t threads_seen = 0;
};

// Renders the case (from `scene`, the case's scene as loaded) on exactly `threads` threads (an arena of that size,
// oversubscribing the machine if need be).
Rendered render_case(const Case& c, int threads, const Scene& scene) {
  RenderOptions o;
  o.spp = c.spp;
  o.seed = 7;
  o.variance = true;
  o.replicates = c.replicates;
  o.layers = c.layers;
  o.tile_size = 8;
  const int x0 = scene.width / 2 - 48, y0 = scene.height / 2 - 32;
  o.window = PixelWindow{x0, y0, x0 + 96, y0 + 64};
  // Which threads finished tiles. With more than one thread, the first row of tiles to finish holds its thread until
  // another thread has finished a tile (30 s at most), so every multi-threaded case really renders on several threads
  // whatever the machine's load: the thread held takes no tiles, so the others must.
  std::set<std::thread::id> seen;
  std::mutex seen_mutex;
  std::condition_variable another_thread;
  o.progress = [&](const RenderProgress&) {
    std::lock_guard lock(seen_mutex);
    seen.insert(std::this_thread::get_id());
    another_thread.notify_all();
  };
  bool held = false;
  if (threads > 1)
    o.rows_final = [&](const Image&, const RenderState&, int, int) {
      if (held) return;
      held = true;
      std::unique_lock lock(seen_mutex);
      another_thread.wait_for(lock, std::chrono::seconds(30), [&] {
        return std::any_of(seen.begin(), seen.end(), [](std::thread::id t) { return t != std::this_thread::get_id(); });
      });
    };
  tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(threads));
  tbb::task_arena arena(threads);
  RenderResult r;
  arena.execute([&] { r = render(scene, o); });
  return {pixel_hash(r.image), seen.size()};
}

Rendered render_case(const Case& c, int threads) { return render_case(c, threads, scene_of(c.scene)); }

std::map<std::string, std::string> read_goldens() {
  std::map<std::string, std::string> g;
  std::ifstream in(kGolden);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::string name, hash;
    ss >> name >> hash;
    g[name] = hash;
  }
  return g;
}

TEST(Determinism, ThreadCounts1237GiveBitwiseTheSamePixels) {
  for (const Case& c : kCases) {
    const Rendered one = render_case(c, 1);
    for (int threads : {2, 3, 7}) {
      const Rendered r = render_case(c, threads);
      std::printf("%s: %d threads (%zu took tiles): %s\n", c.name.c_str(), threads, r.threads_seen, r.hash.c_str());
      EXPECT_EQ(one.hash, r.hash) << c.name << " with " << threads << " threads";
      EXPECT_GT(r.threads_seen, 1U) << c.name << " with " << threads << " threads rendered on one thread only";
    }
  }
}

// Loading decodes images on OpenEXR's threads and builds an environment map's sampling tables row by row on TBB's:
// the scene, and so every pixel, must not depend on how many threads did that.
TEST(Determinism, LoadingOnAnyThreadCountGivesTheSamePixels) {
  for (const Case& c : kCases) {
    if (c.name != "sky_sun" && c.name != "cbox_env_light") continue;
    std::string first;
    for (int threads : {1, 3, 7}) {
      LoadedScene loaded;
      {
        tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(threads));
        tbb::task_arena arena(threads);
        arena.execute([&] { loaded = load_scene_file(kScenes / c.scene); });
      }
      const std::string hash = render_case(c, 2, loaded.scene).hash;
      if (first.empty()) first = hash;
      EXPECT_EQ(first, hash) << c.name << " loaded on " << threads << " threads";
    }
  }
}

TEST(Determinism, RendersMatchTheGoldenChecksums) {
  const auto goldens = read_goldens();
  std::string lines;
  for (const Case& c : kCases) {
    const std::string hash = render_case(c, 2).hash;
    lines += c.name + " " + hash + "\n";
    const auto it = goldens.find(c.name);
    EXPECT_TRUE(it != goldens.end() && it->second == hash)
        << c.name << ": pixels " << hash << ", golden " << (it == goldens.end() ? "(none)" : it->second);
  }
  if (std::getenv("TESSERA_UPDATE_GOLDEN")) {
    std::ofstream out(kGolden);
    out << "# SHA-256 of the pixels (core/render/determinism_test.cpp, pixel_hash) of small renders of scenes/: a 96x64\n"
           "# window at the image centre, 8 spp, seed 7, variance channels (the *_layers renders: every output layer).\n"
           "# A change here means a changed pixel: only a deliberate change of the estimator may update it, in the same\n"
           "# commit, with the reason in its message.\n"
        << lines;
    std::printf("rewrote %s\n", kGolden.c_str());
  }
}

}  // namespace
}  // namespace tessera
