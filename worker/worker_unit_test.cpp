#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"
#include "tests/support/test_files.h"
#include "worker/arena_pinning.h"
#include "worker/asset_cache.h"
#include "worker/job_scenes.h"
#include "client/backoff.h"
#include "worker/recent_log.h"
#include "worker/scene_cache.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstring>
#include <fstream>
#include <sched.h>
#include <atomic>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace tessera::worker {
namespace {

namespace fs = std::filesystem;

// The cache in a folder of the test's own, removed after it.
class AssetCacheTest : public tessera::testing::TempDirTest {};

TEST(Backoff, GrowsToTheCapWithJitterAndResets) {
  client::Backoff b(std::chrono::milliseconds(100), std::chrono::milliseconds(1000));
  const long long expected_base[] = {100, 200, 400, 800, 1000, 1000};
  for (long long base : expected_base) {
    const auto d = b.next().count();
    EXPECT_GE(d, base / 2);
    EXPECT_LE(d, base);
  }
  b.reset();
  EXPECT_LE(b.next().count(), 100);
}

TEST(RecentLog, KeepsTheLastLinesAboutOneLeaseBounded) {
  RecentLogScope scope;
  for (int i = 0; i < 30; ++i) spdlog::info("worker=w-1 job=j-1 tile=0 lease=l-1: step {}", i);
  spdlog::info("worker=w-1 job=j-1 tile=1 lease=l-12: another lease");
  spdlog::info("unrelated line");
  const auto lines = scope.log().lines_with("lease=l-1:", 20, 1000);
  ASSERT_EQ(lines.size(), 20u);
  EXPECT_NE(lines.front().find("step 10"), std::string::npos);  // oldest first, the last 20
  EXPECT_NE(lines.back().find("step 29"), std::string::npos);
  EXPECT_EQ(scope.log().lines_with("lease=l-1:", 5, 10).back().size(), 10u);  // each cut to the byte bound
  EXPECT_EQ(scope.log().lines_with("lease=l-12:", 20, 1000).size(), 1u);
}

TEST(LruCache, EvictsTheLeastRecentlyUsed) {
  LruCache<int> c(2);
  c.put("a", std::make_shared<int>(1));
  c.put("b", std::make_shared<int>(2));
  ASSERT_TRUE(c.find("a"));  // a is now newer than b
  c.put("c", std::make_shared<int>(3));
  EXPECT_EQ(c.size(), 2u);
  EXPECT_FALSE(c.find("b"));
  EXPECT_EQ(*c.find("a"), 1);
  EXPECT_EQ(*c.find("c"), 3);
}

TEST_F(AssetCacheTest, FetchesOnceAndVerifies) {
  AssetCache cache(file("cache"));
  const std::string bytes = "v 0 0 0\n";
  const std::string hash = sha256_hex(bytes);
  int fetches = 0;
  const auto fetch = [&](const std::string& h) {
    EXPECT_EQ(h, hash);
    ++fetches;
    return bytes;
  };
  const fs::path p = cache.get(hash, fetch);
  EXPECT_EQ(cache.get(hash, fetch), p);
  EXPECT_EQ(fetches, 1);
  std::ifstream in(p, std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), bytes);

  // A second process (a fresh cache object on the same folder) finds the file and does not fetch.
  AssetCache again(cache.dir());
  EXPECT_EQ(again.get(hash, fetch), p);
  EXPECT_EQ(fetches, 1);
}

TEST_F(AssetCacheTest, RefusesBytesThatHashToSomethingElse) {
  AssetCache cache(file("cache"));
  const std::string hash = sha256_hex("the real bytes");
  try {
    cache.get(hash, [](const std::string&) { return std::string("tampered"); });
    FAIL();
  } catch (const AssetError& e) {
    EXPECT_NE(std::string(e.what()).find("hashing to " + sha256_hex("tampered")), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(cache.path_of(hash)));
  EXPECT_THROW(cache.get("not-a-hash", [](const std::string&) { return std::string(); }), AssetError);
}

TEST_F(AssetCacheTest, ReplacesACorruptFile) {
  AssetCache cache(file("cache"));
  const std::string bytes = "good";
  const std::string hash = sha256_hex(bytes);
  fs::create_directories(cache.path_of(hash).parent_path());
  std::ofstream(cache.path_of(hash)) << "bad";
  int fetches = 0;
  cache.get(hash, [&](const std::string&) {
    ++fetches;
    return bytes;
  });
  EXPECT_EQ(fetches, 1);
  EXPECT_EQ(sha256_file(cache.path_of(hash)), hash);
}

// A job whose scene (minimal_scene() with a quad mesh) has its one asset in the cache.
class JobScenesTest : public tessera::testing::TempDirTest {
 protected:
  void SetUp() override {
    tessera::testing::TempDirTest::SetUp();
    const std::string obj = tessera::testing::rect_obj({-1, -1, -1}, {2, 0, 0}, {0, 2, 0});
    hash_ = sha256_hex(obj);
    AssetCache(file("cache")).get(hash_, [&](const std::string&) { return obj; });
    job_.scene = tessera::testing::minimal_scene();
    job_.scene["objects"].push_back({{"type", "mesh"}, {"path", "quad.obj"}, {"material_name", "white_diffuse"}});
    job_.assets["quad.obj"] = hash_;
  }
  // The spec the coordinator would send for job_ at `spp`.
  protocol::JobSpec spec(uint32_t spp) const {
    protocol::JobSpec s;
    s.scene = job_.scene;
    s.assets = job_.assets;
    s.sampling = job_.sampling;
    s.sampling.spp = spp;
    s.width = 4;
    s.height = 3;
    return s;
  }
  static std::string no_fetch(const std::string& h) { throw std::runtime_error("fetched " + h); }
  std::string hash_;
  protocol::JobSubmission job_;
};

TEST_F(JobScenesTest, APreloadedSceneIsTakenByTheFirstJobWithTheSameSceneAssetsAndLoading) {
  JobScenes scenes(file("cache"), 3, 1 << 20);
  scenes.preload(job_);
  // Another scene, or the same one loaded another way: loaded on its own, the preload kept.
  protocol::JobSpec other = spec(4);
  other.scene["camera"]["fov"] = 30;
  EXPECT_TRUE(scenes.build("j-other", other, no_fetch));
  protocol::JobSpec median = spec(4);
  median.sampling.bvh = "median";
  EXPECT_TRUE(scenes.build("j-median", median, no_fetch));
  EXPECT_EQ(scenes.preloads_used(), 0);
  // The same scene at any spp: the preloaded one, which renders as a scene loaded for the job does.
  const auto taken = scenes.build("j-1", spec(8), no_fetch);
  EXPECT_EQ(scenes.preloads_used(), 1);
  EXPECT_EQ(taken->sampling.spp, 8u);
  EXPECT_EQ(scenes.find("j-1"), taken);
  const auto fresh = scenes.build("j-2", spec(8), no_fetch);
  EXPECT_EQ(scenes.preloads_used(), 1);  // taken once
  RenderOptions ro;
  ro.spp = 4;
  const Image a = render(taken->loaded.scene, ro).image;
  const Image b = render(fresh->loaded.scene, ro).image;
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)), 0);
}

TEST_F(JobScenesTest, APreloadThatFailsLeavesTheJobToLoadAndReportAsUsual) {
  JobScenes scenes(file("cache"), 3, 1 << 20);
  protocol::JobSubmission missing = job_;
  const std::string obj = tessera::testing::rect_obj({-1, -1, -2}, {2, 0, 0}, {0, 2, 0});
  missing.assets["quad.obj"] = sha256_hex(obj);  // not in the cache: the preload cannot load it
  scenes.preload(missing);
  protocol::JobSpec s = spec(2);
  s.assets = missing.assets;
  int fetched = 0;
  EXPECT_TRUE(scenes.build("j-1", s, [&](const std::string&) {
    ++fetched;
    return obj;
  }));
  EXPECT_EQ(fetched, 1);
  EXPECT_EQ(scenes.preloads_used(), 0);

  // A scene that does not load: the job's build says why, as without a preload.
  protocol::JobSubmission broken = job_;
  broken.scene["objects"][0]["radius"] = -1;
  JobScenes again(file("cache"), 3, 1 << 20);
  again.preload(broken);
  protocol::JobSpec b = spec(2);
  b.scene = broken.scene;
  EXPECT_THROW(again.build("j-2", b, no_fetch), SceneError);
}

}  // namespace
}  // namespace tessera::worker

TEST(CpuList, ParsesRangesAndListsAndRefusesNonsense) {
  using tessera::worker::parse_cpu_list;
  EXPECT_EQ(parse_cpu_list("0"), (std::vector<int>{0}));
  EXPECT_EQ(parse_cpu_list("3,0-2,2"), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(parse_cpu_list("6,4"), (std::vector<int>{4, 6}));
  for (const char* bad : {"", "a", "1-", "-1", "3-1", "1,,2", "1;2", "0 ", "99999"}) {
    EXPECT_THROW(parse_cpu_list(bad), std::invalid_argument) << bad;
  }
}

// Each thread of the arena runs on its slot's CPU while it works there, and the thread that entered it has its CPUs
// back afterwards.
TEST(ArenaPinning, PinsEachSlotToItsCpuAndGivesTheCpusBack) {
  const std::vector<int> cpus = tessera::worker::allowed_cpus();
  ASSERT_FALSE(cpus.empty());
  const int threads = int(std::min<size_t>(cpus.size(), 2));
  // TBB's worker threads outlive the arena and may still hold the observer's registration when the process exits,
  // which LeakSanitizer then reports (about one run in 40): the scheduler is finalized before the test ends, so
  // that its threads have let go.
  tbb::task_scheduler_handle scheduler{tbb::attach{}};
  std::atomic<int> wrong{0}, seen{0};
  {
    tbb::task_arena arena(threads);
    tessera::worker::ArenaPinning pinning(arena, cpus);
    arena.execute([&] {
      tbb::parallel_for(0, 2000, [&](int) {
        const int slot = tbb::this_task_arena::current_thread_index();
        const int cpu = sched_getcpu();
        if (cpu != cpus[size_t(slot) % cpus.size()]) wrong.fetch_add(1);
        seen.fetch_add(1);
      });
    });
  }
  tbb::finalize(scheduler, std::nothrow);  // false when other TBB work of this process is still alive: no matter
  EXPECT_EQ(seen.load(), 2000);
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(tessera::worker::allowed_cpus(), cpus);  // this thread (slot 0 while inside) has every CPU again
}
