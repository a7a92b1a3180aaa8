// morton_order: a permutation, ties by index, neighbours in the order close in space, and the
// refused inputs.
#include "mesh/morton.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/error.hpp"

namespace ks {
namespace {

TEST(Morton, OrdersPointsAlongTheCurve) {
  // The eight corners of a cube, listed backwards: the curve visits x first, then y, then z.
  Eigen::MatrixXd P(8, 3);
  for (int i = 0; i < 8; ++i) {
    const int c = 7 - i;
    P.row(i) << (c & 1), (c >> 1) & 1, (c >> 2) & 1;
  }
  EXPECT_EQ(morton_order(P, 1), (std::vector<int>{7, 6, 5, 4, 3, 2, 1, 0}));
  // Two points in one cell keep their index order.
  Eigen::MatrixXd Q(3, 3);
  Q << 1, 1, 1, 0, 0, 0, 0.001, 0, 0;
  EXPECT_EQ(morton_order(Q, 4), (std::vector<int>{1, 2, 0}));
}

TEST(Morton, ConsecutivePointsAreCloseTogether) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  const int n = 5000;
  Eigen::MatrixXd P(n, 3);
  for (int i = 0; i < n; ++i) P.row(i) << U(rng), U(rng), 0.5 * U(rng);
  const std::vector<int> ord = morton_order(P);
  ASSERT_EQ(ord.size(), size_t(n));
  std::vector<int> seen(size_t(n), 0);
  for (int i : ord) {
    ASSERT_GE(i, 0);
    ASSERT_LT(i, n);
    ++seen[size_t(i)];
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), n);
  auto walk = [&](auto index) {
    double sum = 0;
    for (int k = 1; k < n; ++k) sum += (P.row(index(k)) - P.row(index(k - 1))).norm();
    return sum / (n - 1);
  };
  const double by_index = walk([](int k) { return k; });
  const double by_curve = walk([&](int k) { return ord[size_t(k)]; });
  EXPECT_LT(by_curve, 0.2 * by_index) << by_curve << " against " << by_index;
}

TEST(Morton, RefusesBadInput) {
  EXPECT_TRUE(morton_order(Eigen::MatrixXd(0, 3)).empty());
  EXPECT_EQ(morton_order(Eigen::MatrixXd::Zero(3, 3)), (std::vector<int>{0, 1, 2}));
  EXPECT_THROW(morton_order(Eigen::MatrixXd::Zero(4, 2)), Error);
  EXPECT_THROW(morton_order(Eigen::MatrixXd::Zero(4, 3), 0), Error);
  EXPECT_THROW(morton_order(Eigen::MatrixXd::Zero(4, 3), 11), Error);
}

}  // namespace
}  // namespace ks
