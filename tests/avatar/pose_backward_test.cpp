// pose_avatar_backward (registration's gradient of the posed Gaussians w.r.t. the pose) against
// finite differences through pose_avatar itself, with anisotropic, rotated Gaussians, blended
// skin weights and pose correctives.
#include <gtest/gtest.h>

#include <random>

#include "avatar/pose.hpp"
#include "avatar/tiny_avatar.hpp"
#include "core/error.hpp"
#include "grad_check.hpp"

namespace ks {
namespace {

TEST(AvatarPoseBackward, MatchesFiniteDifferences) {
  std::mt19937_64 rng(5);
  for (const bool correctives : {false, true}) {
    Avatar a = test::tiny_avatar(1);
    if (correctives) {
      const auto v = test::randv(size_t(3 * a.num_gaussians()) * 18, rng, -0.05, 0.05);
      a.posedirs.resize(3 * a.num_gaussians(), 18);
      for (Eigen::Index k = 0; k < a.posedirs.size(); ++k)
        a.posedirs.data()[k] = float(v[size_t(k)]);
    }
    // A linear functional of the posed means and (raw) rotations.
    const auto cm = test::randv(3 * size_t(a.num_gaussians()), rng);
    const auto cq = test::randv(4 * size_t(a.num_gaussians()), rng);
    std::vector<float> dm(cm.begin(), cm.end()), dq(cq.begin(), cq.end());
    auto params = [&](const std::vector<double>& x) {
      BodyParams p;
      p.global_orient = Eigen::Vector3d(x[0], x[1], x[2]);
      p.body_pose = Eigen::VectorXd(6);
      for (int i = 0; i < 6; ++i) p.body_pose[i] = x[3 + size_t(i)];
      p.transl = Eigen::Vector3d(x[9], x[10], x[11]);
      return p;
    };
    auto f = [&](const std::vector<double>& x) {
      const Gaussians g = pose_avatar(a, params(x));
      double s = 0;
      for (size_t k = 0; k < g.means.size(); ++k) s += cm[k] * g.means[k];
      for (size_t k = 0; k < g.quats.size(); ++k) s += cq[k] * g.quats[k];
      return s;
    };
    const std::vector<double> x = {0.3, -0.6, 0.2, 0.5, 0.1, -0.4, -0.3, 0.7, 0.2, 0.1, -0.2, 2.0};
    Gaussians posed;
    AvatarPoseState st;
    pose_avatar(a, params(x), posed, st);
    // The state-keeping forward is pose_avatar's.
    const Gaussians plain = pose_avatar(a, params(x));
    EXPECT_EQ(posed.means, plain.means);
    EXPECT_EQ(posed.quats, plain.quats);
    Eigen::MatrixXd dpose;
    Eigen::Vector3d dtr;
    pose_avatar_backward(a, st, dm, dq, dpose, dtr);
    ASSERT_EQ(dpose.rows(), 3);
    std::vector<double> g(12);
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) g[size_t(3 * r + k)] = dpose(r, k);
    for (int k = 0; k < 3; ++k) g[9 + size_t(k)] = dtr[k];
    // The forward is float: a step of 1e-3 and a tolerance of 1e-3.
    test::expect_grad(f, x, g, 1e-3, 1e-3);
  }
}

TEST(AvatarPoseBackward, RefusesMismatchedGradients) {
  const Avatar a = test::tiny_avatar();
  BodyParams p;
  Gaussians posed;
  AvatarPoseState st;
  pose_avatar(a, p, posed, st);
  Eigen::MatrixXd dpose;
  Eigen::Vector3d dtr;
  EXPECT_THROW(
      pose_avatar_backward(a, st, std::vector<float>(5), std::vector<float>(24), dpose, dtr),
      Error);
  AvatarPoseState empty;
  EXPECT_THROW(pose_avatar_backward(a, empty, posed.means, posed.quats, dpose, dtr), Error);
}

}  // namespace
}  // namespace ks
