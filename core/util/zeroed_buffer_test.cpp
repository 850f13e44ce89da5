#include "core/util/zeroed_buffer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>

namespace tessera {
namespace {

// The values are v.assign(n, T{})'s whatever the size: none, less than a huge page, and several huge pages, with
// old contents replaced.
TEST(AssignZeroed, HoldsNZerosLikeAssign) {
  for (const size_t n : {size_t(0), size_t(1), size_t(1000), size_t(3) << 20}) {
    std::vector<float> v(17, 2.5f);
    assign_zeroed(v, n);
    ASSERT_EQ(v.size(), n);
    EXPECT_TRUE(std::all_of(v.begin(), v.end(), [](float x) { return x == 0.f; })) << n;
    std::vector<uint32_t> u;
    assign_zeroed(u, n);
    ASSERT_EQ(u.size(), n);
    EXPECT_TRUE(std::all_of(u.begin(), u.end(), [](uint32_t x) { return x == 0U; })) << n;
  }
}

// Advice on memory that is not a huge page's worth, or on no memory at all, does nothing (and does not crash).
TEST(AssignZeroed, AdviceOnSmallOrNoMemoryIsHarmless) {
  advise_huge_pages(nullptr, 0);
  advise_huge_pages(nullptr, size_t(4) << 20);
  std::vector<char> small(4096, 'x');
  advise_huge_pages(small.data(), small.size());
  EXPECT_EQ(small[4095], 'x');
}

}  // namespace
}  // namespace tessera
