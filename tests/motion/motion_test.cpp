#include "motion/motion.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.hpp"

namespace ks {

namespace {

Eigen::Matrix3d rot(const Eigen::Vector3d& aa) {
  const double a = aa.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, aa / a).toRotationMatrix();
}

Eigen::Matrix3d joint_rot(const BodyParams& p, int j) {
  return j == 0 ? rot(p.global_orient) : rot(p.body_pose.segment<3>(3 * (j - 1)));
}

double angle_between(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  const double c = std::clamp(((A.transpose() * B).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

// Direction of a limb in the body's frame: the chain's rotations applied to its rest direction.
Eigen::Vector3d chain_dir(const BodyParams& p, std::initializer_list<int> chain,
                          const Eigen::Vector3d& rest_dir) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int j : chain) R = R * joint_rot(p, j);
  return R * rest_dir;
}

}  // namespace

TEST(Motion, BuiltinsHaveTheirLengths) {
  const auto& infos = builtin_motions();
  ASSERT_EQ(infos.size(), 5u);
  for (const char* name : {"turn", "walk", "wave", "dance", "a-t-pose"}) {
    const auto it = std::find_if(infos.begin(), infos.end(),
                                 [&](const MotionInfo& m) { return m.name == name; });
    ASSERT_NE(it, infos.end()) << name;
    EXPECT_FALSE(it->description.empty());
    const Motion m = builtin_motion(name);
    EXPECT_EQ(m.name, name);
    EXPECT_EQ(int(m.frames.size()), it->default_frames);
    const Motion m7 = builtin_motion(name, 7);
    EXPECT_EQ(m7.frames.size(), 7u);
    EXPECT_NEAR(m7.fps * it->default_frames / 7.0, 30.0, 1e-9);  // same duration
    for (const auto& f : m.frames) {
      ASSERT_EQ(f.body_pose.size(), 69);
      ASSERT_TRUE(f.body_pose.allFinite());
      ASSERT_TRUE(f.global_orient.allFinite());
      ASSERT_TRUE(f.transl.allFinite());
    }
  }
  EXPECT_THROW(builtin_motion("moonwalk"), Error);
  EXPECT_THROW(builtin_motion("turn", -3), Error);
  EXPECT_THROW(load_motion("no-such-motion"), Error);
  EXPECT_EQ(load_motion("wave", 5).frames.size(), 5u);
}

TEST(Motion, BuiltinsAreContinuous) {
  for (const auto& info : builtin_motions()) {
    const Motion m = builtin_motion(info.name);
    double max_rot = 0, max_step = 0;
    for (size_t i = 1; i < m.frames.size(); ++i) {
      for (int j = 0; j < 24; ++j)
        max_rot = std::max(max_rot,
                           angle_between(joint_rot(m.frames[i - 1], j), joint_rot(m.frames[i], j)));
      max_step = std::max(max_step, (m.frames[i].transl - m.frames[i - 1].transl).norm());
    }
    EXPECT_LT(max_rot, 12.0) << info.name;   // degrees per frame, any joint
    EXPECT_LT(max_step, 0.06) << info.name;  // metres per frame
    EXPECT_GT(max_rot, 0.1) << info.name;    // and it does move
  }
}

TEST(Motion, TurnCoversFullCircle) {
  const int n = 64;
  const Motion m = builtin_motion("turn", n);
  const double step = 2 * M_PI / n;
  for (int i = 0; i < n; ++i) {
    const auto& g = m.frames[i].global_orient;
    EXPECT_NEAR(g.x(), 0.0, 1e-12);
    EXPECT_NEAR(g.z(), 0.0, 1e-12);
    EXPECT_NEAR(g.y(), i * step, 1e-9);           // continuous yaw, equal steps
    EXPECT_LT(m.frames[i].transl.norm(), 1e-12);  // in place
  }
  // The frames wrap around: one more step after the last frame is a full 360 degrees.
  EXPECT_NEAR(m.frames.back().global_orient.y() + step, 2 * M_PI, 1e-9);
  // Frame 0 faces the camera in the standing pose (no step in progress).
  const BodyParams s = standing_pose();
  EXPECT_LT((m.frames[0].body_pose - s.body_pose).norm(), 0.15);
  // The legs step: some frames lift each knee.
  double max_left = 0, max_right = 0;
  for (const auto& f : m.frames) {
    max_left = std::max(max_left, f.body_pose.segment<3>(3 * (smpl_joint::kLeftKnee - 1)).norm());
    max_right =
        std::max(max_right, f.body_pose.segment<3>(3 * (smpl_joint::kRightKnee - 1)).norm());
  }
  EXPECT_GT(max_left, 0.3);
  EXPECT_GT(max_right, 0.3);
  // The arms hang in the A-pose (62 degrees below horizontal) at the front, side and back views
  // and rise by 30 degrees at the diagonal views, where the torso's sides can be seen.
  using namespace smpl_joint;
  auto arm_drop = [&](int i) {
    const Eigen::Vector3d l =
        chain_dir(m.frames[size_t(i)], {kLeftCollar, kLeftShoulder}, Eigen::Vector3d::UnitX());
    return std::asin(-l.y()) * 180 / M_PI;
  };
  for (int i : {0, 16, 32, 48}) EXPECT_NEAR(arm_drop(i), 62.0, 1.0) << i;
  for (int i : {8, 24, 40, 56}) EXPECT_NEAR(arm_drop(i), 32.0, 1.0) << i;
}

TEST(Motion, StandingPoseLowersTheArms) {
  using namespace smpl_joint;
  const BodyParams p = standing_pose(62.0);
  // Left arm rests along +X, right along -X; lowered they point down and outwards.
  const Eigen::Vector3d l = chain_dir(p, {kLeftCollar, kLeftShoulder}, Eigen::Vector3d::UnitX());
  const Eigen::Vector3d r = chain_dir(p, {kRightCollar, kRightShoulder}, -Eigen::Vector3d::UnitX());
  EXPECT_NEAR(std::asin(-l.y()) * 180 / M_PI, 62.0, 1e-6);
  EXPECT_NEAR(std::asin(-r.y()) * 180 / M_PI, 62.0, 1e-6);
  EXPECT_GT(l.x(), 0.3);
  EXPECT_LT(r.x(), -0.3);
  // Elbows bend the forearms forward (+Z).
  const Eigen::Vector3d lf =
      chain_dir(p, {kLeftCollar, kLeftShoulder, kLeftElbow}, Eigen::Vector3d::UnitX());
  const Eigen::Vector3d rf =
      chain_dir(p, {kRightCollar, kRightShoulder, kRightElbow}, -Eigen::Vector3d::UnitX());
  EXPECT_GT(lf.z(), 0.1);
  EXPECT_GT(rf.z(), 0.1);
  // The wave raises the right forearm above the shoulder mid-way.
  const Motion w = builtin_motion("wave");
  const BodyParams& mid = w.frames[w.frames.size() / 2];
  const Eigen::Vector3d wf =
      chain_dir(mid, {kRightCollar, kRightShoulder, kRightElbow}, -Eigen::Vector3d::UnitX());
  EXPECT_GT(wf.y(), 0.7);
  // The walk moves forwards (+Z) with the legs alternating.
  const Motion walk = builtin_motion("walk");
  EXPECT_GT(walk.frames.back().transl.z() - walk.frames.front().transl.z(), 2.0);
  // The A-T motion reaches the T-pose half-way.
  const Motion at = builtin_motion("a-t-pose", 60);
  const Eigen::Vector3d t =
      chain_dir(at.frames[30], {kLeftCollar, kLeftShoulder}, Eigen::Vector3d::UnitX());
  EXPECT_NEAR(t.y(), 0.0, 1e-9);
}

TEST(Motion, AdaptBodyPose) {
  BodyParams p = standing_pose();
  const Eigen::VectorXd orig = p.body_pose;
  adapt_body_pose(p, 21);
  ASSERT_EQ(p.body_pose.size(), 63);
  EXPECT_EQ(p.body_pose, orig.head(63));
  adapt_body_pose(p, 23);
  ASSERT_EQ(p.body_pose.size(), 69);
  EXPECT_EQ(p.body_pose.tail(6).norm(), 0.0);
}

}  // namespace ks
