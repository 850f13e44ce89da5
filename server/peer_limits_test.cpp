#include "server/peer_limits.h"

#include <gtest/gtest.h>

namespace tessera::server {
namespace {

using Clock = RefusalRate::Clock;
const auto kA = boost::asio::ip::make_address("192.0.2.1");
const auto kB = boost::asio::ip::make_address("2001:db8::1");

TEST(RefusalRate, BlocksAnAddressAtItsLimitUntilTheMinuteEnds) {
  RefusalRate rate(3);
  const Clock::time_point t0 = Clock::now();
  for (int i = 0; i < 2; ++i) rate.note(kA, t0);
  EXPECT_EQ(rate.blocked_for(kA, t0), 0);
  rate.note(kA, t0 + std::chrono::seconds(10));
  EXPECT_EQ(rate.blocked_for(kA, t0 + std::chrono::seconds(10)), 50);
  EXPECT_EQ(rate.blocked_for(kB, t0 + std::chrono::seconds(10)), 0) << "another address is not blocked";
  EXPECT_EQ(rate.blocked_for(kA, t0 + std::chrono::milliseconds(59'500)), 1) << "never 0 while blocked";
  EXPECT_EQ(rate.blocked_for(kA, t0 + std::chrono::seconds(60)), 0) << "a new minute starts afresh";
}

TEST(RefusalRate, ZeroMeansNoLimit) {
  RefusalRate rate(0);
  const Clock::time_point t0 = Clock::now();
  for (int i = 0; i < 1000; ++i) rate.note(kA, t0);
  EXPECT_EQ(rate.blocked_for(kA, t0), 0);
}

}  // namespace
}  // namespace tessera::server
