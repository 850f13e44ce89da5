#include "core/sha256.h"
#include "core/test_files.h"
#include "worker/arena_pinning.h"
#include "worker/asset_cache.h"
#include "client/backoff.h"
#include "worker/recent_log.h"
#include "worker/scene_cache.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <sched.h>
#include <atomic>
#include <tbb/parallel_for.h>

namespace tessera::farm {
namespace {

namespace fs = std::filesystem;

// The cache in a folder of the test's own, removed after it.
class AssetCacheTest : public tessera::testing::TempDirTest {};

TEST(Backoff, GrowsToTheCapWithJitterAndResets) {
  Backoff b(std::chrono::milliseconds(100), std::chrono::milliseconds(1000));
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

}  // namespace
}  // namespace tessera::farm

TEST(CpuList, ParsesRangesAndListsAndRefusesNonsense) {
  using tessera::farm::parse_cpu_list;
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
  const std::vector<int> cpus = tessera::farm::allowed_cpus();
  ASSERT_FALSE(cpus.empty());
  const int threads = int(std::min<size_t>(cpus.size(), 2));
  tbb::task_arena arena(threads);
  tessera::farm::ArenaPinning pinning(arena, cpus);
  std::atomic<int> wrong{0}, seen{0};
  arena.execute([&] {
    tbb::parallel_for(0, 2000, [&](int) {
      const int slot = tbb::this_task_arena::current_thread_index();
      const int cpu = sched_getcpu();
      if (cpu != cpus[size_t(slot) % cpus.size()]) wrong.fetch_add(1);
      seen.fetch_add(1);
    });
  });
  EXPECT_EQ(seen.load(), 2000);
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(tessera::farm::allowed_cpus(), cpus);  // this thread (slot 0 while inside) has every CPU again
}
