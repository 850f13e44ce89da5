#include "server/preview_cache.h"

#include <gtest/gtest.h>

namespace tessera::server {
namespace {

Png png_of(size_t bytes, uint8_t fill) { return std::make_shared<const std::vector<uint8_t>>(bytes, fill); }

TEST(PreviewCache, ServesTheSameBytesForTheSameVersionOnly) {
  PreviewCache cache(1000);
  EXPECT_EQ(cache.find("j-1", "tiles 1"), nullptr);
  const Png png = png_of(100, 7);
  cache.put("j-1", "tiles 1", png);
  const Png again = cache.find("j-1", "tiles 1");
  ASSERT_NE(again, nullptr);
  EXPECT_EQ(again, png);  // the very bytes kept, not encoded again
  EXPECT_EQ(*again, std::vector<uint8_t>(100, 7));
  EXPECT_EQ(cache.find("j-2", "tiles 1"), nullptr);
  EXPECT_EQ(cache.bytes(), 100u);
}

// A new tile changes the job's version: its old preview is not served, and the new one takes its place.
TEST(PreviewCache, ANewVersionInvalidatesTheJobsPreview) {
  PreviewCache cache(1000);
  cache.put("j-1", "tiles 1", png_of(100, 1));
  EXPECT_EQ(cache.find("j-1", "tiles 2"), nullptr);
  cache.put("j-1", "tiles 2", png_of(150, 2));
  EXPECT_EQ(cache.find("j-1", "tiles 1"), nullptr);
  ASSERT_NE(cache.find("j-1", "tiles 2"), nullptr);
  EXPECT_EQ(cache.find("j-1", "tiles 2")->front(), 2);
  EXPECT_EQ(cache.size(), 1u);
  EXPECT_EQ(cache.bytes(), 150u);
  cache.erase("j-1");
  EXPECT_EQ(cache.size(), 0u);
  EXPECT_EQ(cache.bytes(), 0u);
}

TEST(PreviewCache, EvictsTheLeastRecentlyUsedByBytes) {
  PreviewCache cache(1000);
  cache.put("a", "v", png_of(400, 1));
  cache.put("b", "v", png_of(400, 2));
  ASSERT_NE(cache.find("a", "v"), nullptr);  // a is now more recently used than b
  cache.put("c", "v", png_of(400, 3));       // 1200 bytes: b goes
  EXPECT_EQ(cache.find("b", "v"), nullptr);
  EXPECT_NE(cache.find("a", "v"), nullptr);
  EXPECT_NE(cache.find("c", "v"), nullptr);
  EXPECT_EQ(cache.bytes(), 800u);
  cache.put("d", "v", png_of(1000, 4));      // the whole budget: everything else goes
  EXPECT_EQ(cache.size(), 1u);
  EXPECT_EQ(cache.bytes(), 1000u);
  cache.put("e", "v", png_of(1001, 5));      // larger than the budget: never kept
  EXPECT_EQ(cache.find("e", "v"), nullptr);
  EXPECT_EQ(cache.bytes(), 1000u);
}

}  // namespace
}  // namespace tessera::server
