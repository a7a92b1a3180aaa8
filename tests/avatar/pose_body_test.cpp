// Playback posing against the body model's own forward pass.
#include <gtest/gtest.h>

#include <random>

#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"

namespace ks {
namespace {

TEST(AvatarPoseBody, AnchorsMatchBodyForward) {
  const BodyModel& model = default_body_model();
  Eigen::VectorXd betas = Eigen::VectorXd::Zero(std::min(model.num_betas, 2));
  if (betas.size() > 0) betas[0] = 0.5;
  const Avatar a = avatar_from_body(model, betas);
  ASSERT_EQ(a.num_gaussians(), model.num_vertices());
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  BodyParams p;
  p.betas = betas;
  p.global_orient = Eigen::Vector3d(u(rng), u(rng), u(rng));
  p.body_pose.resize(3 * model.num_body_pose_joints());
  for (int k = 0; k < p.body_pose.size(); ++k) p.body_pose[k] = u(rng);
  p.transl = Eigen::Vector3d(0.1, -0.2, 0.3);
  const BodyState st = body_forward(model, p);
  // Joint transforms agree with body_forward's.
  const auto A = avatar_joint_transforms(a, p);
  for (int j = 0; j < model.num_joints(); ++j) EXPECT_LT((A[j] - st.transforms[j]).norm(), 1e-9);
  // Vertices agree wherever the model's skin has at most 4 influences (top-4 exact).
  const Gaussians g = pose_avatar(a, p);
  int compared = 0;
  for (int v = 0; v < model.num_vertices(); ++v) {
    int nz = 0;
    for (int j = 0; j < model.num_joints(); ++j) nz += model.weights(v, j) > 0;
    if (nz > 4) continue;
    ++compared;
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(g.means[3 * v + k], st.vertices(v, k), 2e-4) << "vertex " << v;
  }
  EXPECT_GT(compared, model.num_vertices() / 2);
}

}  // namespace
}  // namespace ks
