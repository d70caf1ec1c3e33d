// core/stats.hpp: the one median of the project (odd and even counts, order, empty sample).

#include "cairn/core/stats.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cairn {
namespace {

TEST(Stats, MedianOfOddAndEvenSamplesWhateverTheirOrder) {
  EXPECT_EQ(median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(median({4.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_EQ(median({-1.0, 5.0}), 2.0);
  EXPECT_EQ(median({7.0}), 7.0);
  EXPECT_EQ(median({1.0, 1.0, 9.0, 9.0, 1.0, 9.0}), 5.0);
  EXPECT_TRUE(std::isnan(median({})));
}

}  // namespace
}  // namespace cairn
