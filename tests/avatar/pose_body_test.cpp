// Playback posing against the body model's own forward pass.
#include <gtest/gtest.h>

#include <random>

#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "evaluate/metrics.hpp"
#include "raster/rasterizer.hpp"

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

// Back-face culling drops a large share of the Gaussians and leaves the image nearly unchanged,
// even with the far side coloured differently from the near side.
TEST(AvatarPoseBody, BackfaceCullKeepsTheImage) {
  const BodyModel& model = default_body_model();
  const Eigen::VectorXd betas = Eigen::VectorXd::Zero(std::min(model.num_betas, 2));
  PlainAvatarOptions opt;
  opt.subdivide = 1;
  Avatar a = avatar_from_body(model, betas, opt);
  const std::vector<float> normals = avatar_anchor_normals(a);
  ASSERT_EQ(normals.size(), a.anchors.size());
  const float C0 = 0.28209479f;
  for (int i = 0; i < a.num_gaussians(); ++i) {  // front (+Z) orange, back blue, by the normal
    const bool front = normals[3 * size_t(i) + 2] > 0.f;
    const float rgb[3] = {front ? 0.9f : 0.1f, front ? 0.5f : 0.2f, front ? 0.1f : 0.9f};
    for (int c = 0; c < 3; ++c) a.gaussians.sh[3 * size_t(i) + c] = (rgb[c] - 0.5f) / C0;
  }
  BodyParams p;
  p.betas = betas;
  p.global_orient = Eigen::Vector3d(0.0, 0.3, 0.0);
  p.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
  const Camera cam = Camera::look_at_fov({0.3, 0.0, 3.0}, {0.0, 0.0, 0.0}, 96, 160, 40.0);
  BackfaceCull cull;
  cull.normals = &normals;
  cull.eye = cam.centre();
  Gaussians full, culled;
  pose_avatar(a, p, full);
  pose_avatar(a, p, culled, &cull);
  int n_culled = 0;
  for (float o : culled.opacity_logits) n_culled += o == kCulledOpacityLogit;
  EXPECT_GT(n_culled, a.num_gaussians() / 3);
  RasterResult r1, r2;
  rasterize_forward(full, cam, {}, r1);
  rasterize_forward(culled, cam, {}, r2);
  EXPECT_GT(psnr(r1.color, r2.color), 35.0) << n_culled << " of " << a.num_gaussians() << " culled";
}

}  // namespace
}  // namespace ks
