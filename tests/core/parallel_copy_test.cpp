#include "core/parallel_copy.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <numeric>
#include <vector>

namespace ks {
namespace {

// Sizes below, at and above the parallel threshold, and one not a multiple of the chunk.
const size_t kSizes[] = {0, 1, 1000, kParallelMin - 1, kParallelMin, 3 * kParallelMin + 12345};

TEST(ParallelCopy, CopiesEveryElement) {
  for (size_t n : kSizes) {
    std::vector<float> src(n), dst(n + 1, -1.f);
    std::iota(src.begin(), src.end(), 0.5f);
    parallel_copy(src.data(), n, dst.data());
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(dst[i], src[i]) << "n " << n << " i " << i;
    EXPECT_EQ(dst[n], -1.f) << "wrote past the end, n " << n;
  }
}

TEST(ParallelCopy, AssignLeavesWhatVectorAssignmentLeaves) {
  for (size_t n : kSizes)
    for (size_t before : {size_t(0), n / 2, n + 7}) {
      std::vector<int> src(n), dst(before, 9);
      std::iota(src.begin(), src.end(), 3);
      parallel_assign(dst, src);
      EXPECT_EQ(dst, src) << "n " << n << " from size " << before;
    }
  std::vector<int> self(kParallelMin + 5, 4);
  parallel_assign(self, self);
  EXPECT_EQ(self, std::vector<int>(kParallelMin + 5, 4));
}

TEST(ParallelCopy, FillsExactlyTheRange) {
  for (size_t n : kSizes) {
    std::vector<float> v(n + 2, 1.f);
    parallel_fill(v.data() + 1, n, 0.f);
    EXPECT_EQ(v.front(), 1.f);
    EXPECT_EQ(v.back(), 1.f);
    for (size_t i = 1; i <= n; ++i) ASSERT_EQ(v[i], 0.f) << "n " << n << " i " << i;
  }
}

TEST(ParallelCopy, EqualAsVectorEquality) {
  for (size_t n : kSizes) {
    std::vector<float> a(n);
    std::iota(a.begin(), a.end(), 1.f);
    std::vector<float> b = a;
    EXPECT_TRUE(parallel_equal(a, b)) << n;
    if (n == 0) continue;
    for (size_t at : {size_t(0), n / 2, n - 1}) {
      b[at] += 1.f;
      EXPECT_FALSE(parallel_equal(a, b)) << "n " << n << " at " << at;
      b[at] = a[at];
    }
    b.push_back(0.f);
    EXPECT_FALSE(parallel_equal(a, b)) << "sizes differ, n " << n;
  }
  std::vector<float> nan(kParallelMin + 1, 0.f);
  nan[kParallelMin] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(parallel_equal(nan, nan));  // as operator== (NaN != NaN)
}

}  // namespace
}  // namespace ks
