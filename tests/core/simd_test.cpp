// core/simd.hpp: the lane helpers that are more than one vector operation.
#include "core/simd.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace ks {
namespace {

// Every x of `xs` through log_at_least_one, CW at a time: no lane below the exact log(max(x, 1))
// (in double), none above it by more than max_excess.
template <int CW>
void check_log(const std::vector<float>& xs, double max_excess) {
  using L = Lanes<CW>;
  for (size_t i = 0; i < xs.size(); i += CW) {
    typename L::V x;
    for (int l = 0; l < CW; ++l) x[l] = xs[std::min(xs.size() - 1, i + size_t(l))];
    const typename L::V y = L::log_at_least_one(x);
    for (int l = 0; l < CW; ++l) {
      const double exact = std::log(std::max(double(x[l]), 1.0));
      ASSERT_GE(double(y[l]), exact) << "x = " << x[l];
      ASSERT_LE(double(y[l]) - exact, max_excess) << "x = " << x[l];
    }
  }
}

TEST(SimdLanes, LogAtLeastOneNeverFallsBelowTheExactValue) {
  std::vector<float> xs = {0.f,         -3.f,
                           1e-40f,      0.5f,
                           1.f,         std::nextafter(1.f, 2.f),
                           255.f,       std::nextafter(1.41421356f, 0.f),
                           1.41421356f, std::nextafter(1.41421356f, 2.f),
                           2.f,         1e6f,
                           16777216.f};
  // Every float of [1, 2) at a stride, the rasterizer's range [1, 255] densely, and random ones
  // up to 2^24.
  for (float x = 1.f; x < 2.f; x = std::nextafter(x, 3.f) + 1e-6f) xs.push_back(x);
  for (int k = 0; k <= 255000; ++k) xs.push_back(1.f + float(k) * (254.f / 255000.f));
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.f, 24.f);
  for (int k = 0; k < 100000; ++k) xs.push_back(std::exp2(U(rng)));
  check_log<4>(xs, 6e-6);
  check_log<8>(xs, 6e-6);
}

TEST(SimdLanes, LogAtLeastOneIsZeroPlusTheMarginBelowOne) {
  using L = Lanes<4>;
  const L::V y = L::log_at_least_one(L::V{0.f, 0.25f, 0.999f, 1.f});
  for (int l = 0; l < 4; ++l) {
    EXPECT_GE(y[l], 0.f);
    EXPECT_LE(y[l], 5e-6f);
  }
}

}  // namespace
}  // namespace ks
