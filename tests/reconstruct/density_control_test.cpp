#include <gtest/gtest.h>

#include <cmath>

#include "core/error.hpp"
#include "reconstruct/density.hpp"
#include "reconstruct/density_ops.hpp"

namespace ks {
namespace {

TrainerState sphere_state(int levels) {
  Eigen::MatrixXd V(6, 3);
  V << 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1;
  Eigen::MatrixXi F(8, 3);
  F << 0, 2, 4, 4, 2, 1, 1, 2, 5, 5, 2, 0, 0, 4, 3, 4, 1, 3, 1, 5, 3, 5, 0, 3;
  for (int l = 0; l < levels; ++l) {
    const MeshEdit e = split_faces(F, int(V.rows()), std::vector<uint8_t>(F.rows(), 1));
    V = e.S * V;
    F = e.faces;
  }
  V.rowwise().normalize();
  TrainerState s;
  s.total_iterations = 100;
  s.anchors = V;
  s.faces = F;
  const int N = int(V.rows());
  s.part_labels.assign(N, 0);
  s.skin_joints.assign(4 * N, 0);
  s.skin_weights.assign(4 * N, 0.f);
  for (int i = 0; i < N; ++i) s.skin_weights[4 * i] = 1.f;
  s.log_scale_bias.assign(N, 0.f);
  s.grad2d_accum.assign(N, 0.f);
  s.grad2d_count.assign(N, 1);
  s.max_radius.assign(N, 1);
  s.canonical.resize(N);
  for (int i = 0; i < N; ++i) {
    s.canonical.opacity_logits[i] = 3.f;
    for (int k = 0; k < 3; ++k) {
      s.canonical.means[3 * i + k] = float(V(i, k));
      s.canonical.log_scales[3 * i + k] = std::log(0.05f);
    }
  }
  return s;
}

DensityOptions every_step() {
  DensityOptions o;
  o.start = 1;
  o.stop = 1000;
  o.interval = 1;
  o.grad_threshold = 0.5f * 128.f;  // 0.5 px in NDC units at the assumed 256 px width
  o.max_split_fraction = 1.f;
  return o;
}

TEST(DensityControl, FactoryNamesAndOff) {
  for (const auto& n : density_control_names()) EXPECT_NE(make_density_control(n), nullptr);
  EXPECT_THROW(make_density_control("bogus"), Error);
  TrainerState s = sphere_state(1);
  s.grad2d_accum.assign(s.num_vertices(), 10.f);
  auto off = make_density_control("off", every_step());
  off->step(5, s);
  EXPECT_EQ(s.num_vertices(), 18);
}

TEST(DensityControl, VertexModeSplitsFacesAroundHighGradientVertices) {
  TrainerState s = sphere_state(1);
  const int N = s.num_vertices();
  s.grad2d_accum[0] = 2.f;  // one vertex over tau
  auto c = make_density_control("vertex", every_step());
  c->step(3, s);
  EXPECT_GT(s.num_vertices(), N);
  EXPECT_EQ(int(s.log_scale_bias.size()), s.num_vertices());
  EXPECT_EQ(int(s.canonical.size()), s.num_vertices());
  // Statistics were reset after acting.
  for (float a : s.grad2d_accum) EXPECT_EQ(a, 0.f);
  EXPECT_EQ(density_stats(*c)->added, s.num_vertices() - N);
  // Not due: nothing happens.
  DensityOptions late = every_step();
  late.start = 50;
  auto c2 = make_density_control("vertex", late);
  const int before = s.num_vertices();
  s.grad2d_accum.assign(before, 10.f);
  c2->step(3, s);
  EXPECT_EQ(s.num_vertices(), before);
}

TEST(DensityControl, NaiveModeClonesAndPrunes) {
  TrainerState s = sphere_state(1);
  const int N = s.num_vertices();
  s.canonical.opacity_logits[3] = -9.f;  // pruned
  s.grad2d_accum[0] = 2.f;               // split (scale 0.05 > 1% of extent 1)
  for (int k = 0; k < 3; ++k) s.canonical.log_scales[3 + k] = std::log(0.001f);
  s.grad2d_accum[1] = 2.f;  // clone (tiny)
  auto c = make_density_control("naive", every_step());
  c->step(0, s);
  EXPECT_EQ(s.num_vertices(), N - 1 + 2);
  EXPECT_NEAR(s.log_scale_bias[0], -std::log(1.6f), 1e-6);
}

TEST(DensityControl, GpdcCollapsesTransparentSplitsAndRescales) {
  TrainerState s = sphere_state(2);
  const int N = s.num_vertices();
  // Three transparent vertices far apart, one high-gradient region, one oversized Gaussian.
  for (int i : {10, 30, 50}) s.canonical.opacity_logits[i] = -6.f;
  s.grad2d_accum[0] = 2.f;
  s.grad2d_accum[1] = 2.f;
  for (int k = 0; k < 3; ++k) s.canonical.log_scales[3 * 5 + k] = std::log(1.0f);
  auto c = make_density_control("gpdc", every_step());
  c->step(0, s);
  const DensityStats* st = density_stats(*c);
  EXPECT_GT(st->removed, 0);
  EXPECT_GT(st->added, 0);
  EXPECT_EQ(s.num_vertices(), N - st->removed + st->added);
  EXPECT_GE(st->rescaled, st->added + 1);
  // The oversized Gaussian (index 5, below every removed index) is scaled down to the mean size.
  EXPECT_LT(s.log_scale_bias[5], -2.f);
  // Mesh faces stay consistent with the vertex count (2 faces fewer per collapse, more per split).
  EXPECT_LT(s.faces.maxCoeff(), s.num_vertices());
  EXPECT_EQ(s.faces.rows(), 128 - 2 * st->removed + 2 * st->added);
}

}  // namespace
}  // namespace ks
