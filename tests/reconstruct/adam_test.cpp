#include "reconstruct/adam.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.hpp"

namespace ks {

TEST(Adam, MinimisesQuadraticWithCosineDecay) {
  std::vector<float> p = {3.f, -2.f, 0.5f}, q = {1.f};
  std::vector<float> gp(3), gq(1);
  Adam adam;
  adam.total_steps = 400;
  adam.add_group("p", &p, &gp, 0.05f);
  adam.add_group("q", &q, &gq, 0.0f);  // lr 0: never moves
  for (int it = 0; it < 400; ++it) {
    for (int i = 0; i < 3; ++i) gp[i] = 2 * (p[i] - float(i));
    gq[0] = 1.f;
    adam.step();
  }
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(p[i], float(i), 1e-2);
  EXPECT_EQ(q[0], 1.f);
  EXPECT_NEAR(adam.lr_scale(), adam.final_fraction, 1e-6);
  EXPECT_THROW(adam.add_group("p", &p, &gp, 0.1f), Error);  // names are unique
  EXPECT_THROW(adam.group("missing"), Error);
}

// Active ranges: entries outside them have had zero gradients throughout, so stepping only the
// ranges gives the same bits as stepping everything.
TEST(Adam, ActiveRangesGiveTheSameStepsAsTheWholeGroup) {
  const size_t n = 200000;  // above the parallel threshold
  std::vector<float> p0(n), g(n, 0.f);
  for (size_t i = 0; i < n; ++i) p0[i] = std::sin(float(i));
  const std::vector<std::pair<size_t, size_t>> ranges = {{32, 96}, {1000, 70000}, {150000, n}};
  std::vector<float> pa = p0, pb = p0;
  Adam a, b;
  a.total_steps = b.total_steps = 10;
  a.add_group("t", &pa, &g, 0.01f);
  b.add_group("t", &pb, &g, 0.01f, &ranges);
  for (int it = 0; it < 5; ++it) {
    for (const auto& [lo, hi] : ranges)
      for (size_t i = lo; i < hi; ++i) g[i] = std::cos(float(i + size_t(it)));
    a.step();
    b.step();
  }
  EXPECT_EQ(pa, pb);
  EXPECT_EQ(a.group("t").m, b.group("t").m);
  EXPECT_EQ(a.group("t").v, b.group("t").v);
  EXPECT_NE(pa[40], p0[40]);
  EXPECT_EQ(pa[100], p0[100]);
  const std::vector<std::pair<size_t, size_t>> past = {{0, n + 1}};
  Adam c;
  c.add_group("t", &pb, &g, 0.01f, &past);
  EXPECT_THROW(c.step(), Error);
}

TEST(Adam, ResizeAndRemapKeepMoments) {
  std::vector<float> p = {1, 2, 3, 4, 5, 6};
  std::vector<float> g = {1, 1, 1, -1, -1, -1};
  Adam adam;
  adam.add_group("p", &p, &g, 0.1f);
  adam.step();
  const float m3 = adam.group("p").m[3];
  // Per-vertex stride 3: keep vertex 1 first, then a new vertex.
  adam.remap_group("p", {1, -1}, 3);
  EXPECT_EQ(adam.group("p").m.size(), 6u);
  EXPECT_EQ(adam.group("p").m[0], m3);
  EXPECT_EQ(adam.group("p").m[3], 0.f);
  p.resize(9, 0.f);
  adam.resize_group("p");
  EXPECT_EQ(adam.group("p").v.size(), 9u);
  g.assign(9, 0.5f);
  adam.step();
  g.assign(2, 0.f);
  EXPECT_THROW(adam.step(), std::exception);
  EXPECT_THROW(adam.remap_group("p", {7}, 3), std::exception);
}

// Through a density-control stencil: kept vertices (a row with one entry of 1) keep their
// moments, new vertices (midpoints) and merged ones start at zero.
TEST(Adam, RemapThroughAStencilCarriesTheKeptEntries) {
  std::vector<float> p = {1, 2, 3, 4, 5, 6}, g = {0.5f, -1, 2, 1, 1, -3};
  Adam adam;
  adam.add_group("v", &p, &g, 0.1f);  // 3 vertices, 2 values each
  adam.step();
  const std::vector<float> m = adam.group("v").m, v = adam.group("v").v;
  Eigen::SparseMatrix<double, Eigen::RowMajor> S(4, 3);
  S.insert(0, 2) = 1.0;  // old vertex 2 first
  S.insert(1, 0) = 1.0;  // old vertex 0
  S.insert(2, 0) = 0.5;  // the midpoint of 0 and 1
  S.insert(2, 1) = 0.5;
  S.insert(3, 1) = 0.7;  // a weight that is not 1: a new vertex too
  S.makeCompressed();
  adam.remap_group("v", S);
  const AdamGroup& a = adam.group("v");
  ASSERT_EQ(a.m.size(), 8u);
  EXPECT_EQ(a.m[0], m[4]);
  EXPECT_EQ(a.v[1], v[5]);
  EXPECT_EQ(a.m[2], m[0]);
  EXPECT_EQ(a.v[3], v[1]);
  for (int k = 4; k < 8; ++k) {
    EXPECT_EQ(a.m[size_t(k)], 0.f);
    EXPECT_EQ(a.v[size_t(k)], 0.f);
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> wrong(2, 3);  // 8 moments, not 2 per column
  EXPECT_THROW(adam.remap_group("v", wrong), Error);
}

}  // namespace ks
