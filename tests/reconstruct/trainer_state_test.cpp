#include <gtest/gtest.h>

#include "core/error.hpp"
#include "reconstruct/density.hpp"

namespace ks {

namespace {
TrainerState two_triangles() {
  TrainerState s;
  s.anchors.resize(4, 3);
  s.anchors << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0;
  s.faces.resize(2, 3);
  s.faces << 0, 1, 2, 1, 3, 2;
  s.part_labels = {0, 1, 1, 2};
  s.skin_joints = {0, 1, 0, 0, 1, 2, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0};
  s.skin_weights = {0.5f, 0.5f, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  s.log_scale_bias = {0.f, 1.f, 2.f, 3.f};
  s.grad2d_accum = {1, 1, 1, 1};
  s.grad2d_count = {1, 2, 3, 4};
  s.max_radius = {1, 2, 3, 4};
  return s;
}
}  // namespace

TEST(TrainerState, StencilAddsMidpointAndMapsAttributes) {
  TrainerState s = two_triangles();
  Eigen::SparseMatrix<double, Eigen::RowMajor> S(5, 4);
  std::vector<Eigen::Triplet<double>> t = {{0, 0, 1}, {1, 1, 1},   {2, 2, 1},
                                           {3, 3, 1}, {4, 1, 0.5}, {4, 2, 0.5}};
  S.setFromTriplets(t.begin(), t.end());
  Eigen::MatrixXi F(4, 3);
  F << 0, 1, 4, 0, 4, 2, 1, 3, 4, 4, 3, 2;
  int called = 0;
  s.on_resize_ctx = &called;
  s.on_resize = [](void* c, const Eigen::SparseMatrix<double, Eigen::RowMajor>&) {
    ++*static_cast<int*>(c);
  };
  s.apply_stencil(S, F);
  EXPECT_EQ(called, 1);
  ASSERT_EQ(s.num_vertices(), 5);
  EXPECT_NEAR(s.anchors(4, 0), 0.5, 1e-12);
  EXPECT_NEAR(s.anchors(4, 1), 0.5, 1e-12);
  EXPECT_NEAR(s.log_scale_bias[4], 1.5f, 1e-6);
  // joints 1 and 2 each with 0.5
  float w1 = 0, w2 = 0, sum = 0;
  for (int k = 0; k < 4; ++k) {
    sum += s.skin_weights[16 + k];
    if (s.skin_joints[16 + k] == 1) w1 += s.skin_weights[16 + k];
    if (s.skin_joints[16 + k] == 2) w2 += s.skin_weights[16 + k];
  }
  EXPECT_NEAR(sum, 1.f, 1e-6);
  EXPECT_NEAR(w1, 0.5f, 1e-6);
  EXPECT_NEAR(w2, 0.5f, 1e-6);
  EXPECT_EQ(s.part_labels[4], 1);
  EXPECT_EQ(s.faces.rows(), 4);
}

TEST(TrainerState, StencilRejectsBadInput) {
  TrainerState s = two_triangles();
  Eigen::SparseMatrix<double, Eigen::RowMajor> wrong(3, 5);
  EXPECT_THROW(s.apply_stencil(wrong, s.faces), Error);
  Eigen::SparseMatrix<double, Eigen::RowMajor> S(3, 4);
  std::vector<Eigen::Triplet<double>> t = {{0, 0, 1}, {1, 1, 1}, {2, 2, 1}};
  S.setFromTriplets(t.begin(), t.end());
  Eigen::MatrixXi F(1, 3);
  F << 0, 1, 3;  // index 3 no longer exists
  EXPECT_THROW(s.apply_stencil(S, F), Error);
  Eigen::SparseMatrix<double, Eigen::RowMajor> empty_row(3, 4);
  std::vector<Eigen::Triplet<double>> t2 = {{0, 0, 1}, {1, 1, 1}};
  empty_row.setFromTriplets(t2.begin(), t2.end());
  F << 0, 1, 2;
  EXPECT_THROW(s.apply_stencil(empty_row, F), Error);
}

}  // namespace ks
