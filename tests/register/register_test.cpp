// register_pose: a body avatar rendered at a known pose, the registration started from a
// perturbed one, must come back towards the truth; bad inputs are refused.
#include "register/register.hpp"

#include <gtest/gtest.h>

#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/error.hpp"
#include "raster/rasterizer.hpp"

namespace ks {
namespace {

struct Scene {
  Avatar avatar;
  Camera camera;
  BodyParams truth;
  Image image, mask;
  float bg[3] = {1.f, 1.f, 1.f};
};

Scene make_scene() {
  Scene s;
  const BodyModel& model = default_body_model();
  PlainAvatarOptions ao;
  ao.color[0] = 0.8f, ao.color[1] = 0.3f, ao.color[2] = 0.2f;
  s.avatar = avatar_from_body(model, Eigen::VectorXd::Zero(std::min(model.num_betas, 2)), ao);
  // Colour by part and by side, so that a turn shows in the colours, not only the outline (SH
  // degree 0: colour = 0.5 + C0 * dc).
  const int K = s.avatar.gaussians.coeffs();
  for (int i = 0; i < s.avatar.num_gaussians(); ++i) {
    const float* x = &s.avatar.gaussians.means[3 * size_t(i)];
    const float c[3] = {x[0] > 0 ? 0.9f : 0.2f,
                        0.2f + 0.15f * float(s.avatar.part_labels[size_t(i)] % 5),
                        x[2] > 0.02f ? 0.9f : 0.1f};
    for (int k = 0; k < 3; ++k)
      s.avatar.gaussians.sh[size_t(i) * size_t(K) * 3 + size_t(k)] = (c[k] - 0.5f) / 0.28209479f;
  }
  s.camera =
      Camera::look_at_fov(Eigen::Vector3d(0, 0.2, 3.2), Eigen::Vector3d(0, 0.2, 0), 192, 256, 50);
  s.truth.global_orient = Eigen::Vector3d(0, 0.3, 0);
  s.truth.body_pose = Eigen::VectorXd::Zero(69);
  s.truth.body_pose[3 * 15 + 2] = -0.9;  // left shoulder (joint 16) down
  s.truth.body_pose[3 * 16 + 2] = 0.9;   // right shoulder (joint 17) down
  s.truth.transl = Eigen::Vector3d(0.02, 0.0, 0.0);
  RasterSettings rs;
  for (int k = 0; k < 3; ++k) rs.background[k] = s.bg[k];
  RasterResult rr;
  rasterize_forward(pose_avatar(s.avatar, s.truth), s.camera, rs, rr);
  s.image = rr.color;
  s.mask = rr.alpha;
  return s;
}

double joint_error(const Avatar& a, const BodyParams& p, const BodyParams& q) {
  return (avatar_posed_joints(a, p) - avatar_posed_joints(a, q)).rowwise().norm().mean();
}

TEST(Register, RecoversAPerturbedPose) {
  const Scene s = make_scene();
  BodyParams start = s.truth;
  start.global_orient[1] += 0.15;
  start.transl += Eigen::Vector3d(0.04, -0.03, 0.0);
  start.body_pose[3 * 15 + 2] += 0.3;
  RegisterOptions o;
  o.scales = {0.5f, 1.f};
  o.iterations = {80, 40};
  const RegisterResult r = register_pose(s.avatar, start, s.camera, s.image, s.mask, s.bg, o);
  EXPECT_TRUE(r.improved);
  EXPECT_LT(r.cost_after, 0.5 * r.cost_before);
  EXPECT_LT(r.mask_after, r.mask_before);
  EXPECT_EQ(r.steps, 120);
  const double before = joint_error(s.avatar, start, s.truth);
  const double after = joint_error(s.avatar, r.params, s.truth);
  EXPECT_LT(after, 0.5 * before) << before << " -> " << after << " cost " << r.cost_before << " -> "
                                 << r.cost_after << " go " << r.params.global_orient.transpose()
                                 << " tr " << r.params.transl.transpose() << " sh "
                                 << r.params.body_pose[47];
  // The registered pose has the avatar's layout: all 23 body joints.
  EXPECT_EQ(r.params.body_pose.size(), 69);
}

TEST(Register, KeepsTheStartWhenNothingImproves) {
  const Scene s = make_scene();
  RegisterOptions o;
  o.scales = {1.f};
  o.iterations = {0};
  const RegisterResult r = register_pose(s.avatar, s.truth, s.camera, s.image, s.mask, s.bg, o);
  EXPECT_FALSE(r.improved);
  EXPECT_EQ(r.params.global_orient, s.truth.global_orient);
  EXPECT_EQ(r.cost_after, r.cost_before);
}

TEST(Register, RefusesInconsistentInputs) {
  const Scene s = make_scene();
  const Image small_mask(10, 10, 1, 1.f);
  EXPECT_THROW(register_pose(s.avatar, s.truth, s.camera, s.image, small_mask, s.bg), Error);
  const Camera other = scale_camera(s.camera, 48, 64);
  EXPECT_THROW(register_pose(s.avatar, s.truth, other, s.image, s.mask, s.bg), Error);
  RegisterOptions o;
  o.iterations = {10};
  EXPECT_THROW(register_pose(s.avatar, s.truth, s.camera, s.image, s.mask, s.bg, o), Error);
  o = RegisterOptions();
  o.scales = {0.f, 1.f};
  EXPECT_THROW(register_pose(s.avatar, s.truth, s.camera, s.image, s.mask, s.bg, o), Error);
  EXPECT_THROW(register_pose(s.avatar, s.truth, s.camera, Image(192, 256, 1), s.mask, s.bg), Error);
}

}  // namespace
}  // namespace ks
