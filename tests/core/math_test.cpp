// core/math.hpp: the median every stage uses (issue 58: one statistic for one word).
#include <gtest/gtest.h>

#include "core/math.hpp"

namespace ks {

TEST(Median, OddCountsTheMiddleEvenTheMeanOfTheTwoMiddle) {
  EXPECT_EQ(median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(median({4.0, 1.0, 3.0, 2.0}), 2.5);  // not the upper middle (3)
  EXPECT_EQ(median({5.0}), 5.0);
  EXPECT_EQ(median({7.0, 7.0, 1.0, 9.0}), 7.0);  // equal middle values: either copy agrees
  EXPECT_EQ(median({}), 0.0);                    // none: 0
}

TEST(Median, LeavesItsArgumentAlone) {
  const std::vector<double> v = {3.0, 1.0, 2.0, 0.5};
  EXPECT_EQ(median(v), 1.5);
  EXPECT_EQ(v, (std::vector<double>{3.0, 1.0, 2.0, 0.5}));
}

}  // namespace ks
