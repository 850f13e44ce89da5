#include "server/log_limit.h"

#include <gtest/gtest.h>

namespace tessera::server {
namespace {

using std::chrono::seconds;

TEST(LogLimit, LetsAFewLinesThroughPerPeriodAndCountsTheRest) {
  LogLimit limit(2, seconds(60));
  const auto t0 = std::chrono::steady_clock::time_point{} + seconds(1000);
  uint64_t left_out = 99;
  EXPECT_TRUE(limit.allow(left_out, t0));
  EXPECT_EQ(left_out, 0u);
  EXPECT_TRUE(limit.allow(left_out, t0 + seconds(1)));
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(limit.allow(left_out, t0 + seconds(2)));
  EXPECT_EQ(left_out, 0u) << "a refused line leaves the count alone";
  EXPECT_FALSE(limit.allow(left_out, t0 + seconds(59)));
  // The next period: the first line says how many were left out.
  EXPECT_TRUE(limit.allow(left_out, t0 + seconds(60)));
  EXPECT_EQ(left_out, 1001u);
  EXPECT_TRUE(limit.allow(left_out, t0 + seconds(61)));
  EXPECT_EQ(left_out, 0u);
  EXPECT_EQ(LogLimit::left_out_note(1001, "refusals"), " (1001 more refusals not logged before this one)");
  EXPECT_EQ(LogLimit::left_out_note(0, "refusals"), "");
}

}  // namespace
}  // namespace tessera::server
