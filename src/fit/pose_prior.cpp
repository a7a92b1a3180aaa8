#include "fit/pose_prior.hpp"

#include <algorithm>
#include <cmath>

#include "body/joints.hpp"
#include "motion/motion.hpp"

namespace ks::fit {

namespace {

constexpr double kDeg = M_PI / 180.0;

// Anatomical limits (degrees) of SMPL's body joints 1..23, axis-angle components x, y, z in the
// joint's parent frame (T-pose rest: arms along +-X, legs down -Y, facing +Z).
struct Limit {
  double lo[3], hi[3];
};
const Limit kLimits[24] = {
    {{0, 0, 0}, {0, 0, 0}},              // 0 pelvis (global orientation: free)
    {{-120, -40, -25}, {30, 40, 70}},    // 1 left hip: flexion -x, abduction +z
    {{-120, -40, -70}, {30, 40, 25}},    // 2 right hip
    {{-25, -30, -25}, {45, 30, 25}},     // 3 spine1
    {{0, -10, -10}, {150, 10, 10}},      // 4 left knee: flexion +x
    {{0, -10, -10}, {150, 10, 10}},      // 5 right knee
    {{-25, -30, -25}, {45, 30, 25}},     // 6 spine2
    {{-45, -25, -25}, {45, 25, 25}},     // 7 left ankle
    {{-45, -25, -25}, {45, 25, 25}},     // 8 right ankle
    {{-25, -30, -25}, {45, 30, 25}},     // 9 spine3
    {{-30, -15, -15}, {30, 15, 15}},     // 10 left foot
    {{-30, -15, -15}, {30, 15, 15}},     // 11 right foot
    {{-40, -50, -35}, {50, 50, 35}},     // 12 neck
    {{-20, -20, -30}, {20, 20, 30}},     // 13 left collar
    {{-20, -20, -30}, {20, 20, 30}},     // 14 right collar
    {{-40, -60, -35}, {50, 60, 35}},     // 15 head
    {{-90, -110, -100}, {90, 45, 100}},  // 16 left shoulder: forward swing -y
    {{-90, -45, -100}, {90, 110, 100}},  // 17 right shoulder: forward swing +y
    {{-90, -150, -15}, {90, 0, 15}},     // 18 left elbow: flexion -y
    {{-90, 0, -15}, {90, 150, 15}},      // 19 right elbow: flexion +y
    {{-60, -70, -45}, {60, 70, 45}},     // 20 left wrist
    {{-60, -70, -45}, {60, 70, 45}},     // 21 right wrist
    {{-20, -20, -20}, {20, 20, 20}},     // 22 left hand
    {{-20, -20, -20}, {20, 20, 20}},     // 23 right hand
};

// How far each SMPL body joint (1..23) strays from the natural stance in everyday poses, degrees:
// the swing of the bone and the twist about it.
const double kSigma[24][2] = {
    {0, 0},   {40, 15}, {40, 15}, {10, 10}, {50, 5},  {50, 5},  {10, 10}, {15, 10},
    {15, 10}, {10, 10}, {10, 10}, {10, 10}, {15, 15}, {8, 8},   {8, 8},   {15, 20},
    {50, 20}, {50, 20}, {50, 25}, {50, 25}, {20, 20}, {20, 20}, {10, 10}, {10, 10},
};

}  // namespace

std::vector<JointPrior> make_joint_priors(const BodyData& d, double arm_down_degrees,
                                          double w_limits) {
  const int nj = d.layout.pose_joints;
  const BodyParams stance = standing_pose(arm_down_degrees);
  std::vector<JointPrior> out(static_cast<size_t>(nj));
  for (int j = 1; j <= nj; ++j) {
    JointPrior& p = out[size_t(j - 1)];
    const int child = first_child(d.parents, j);
    Eigen::Vector3d axis = child >= 0 ? Eigen::Vector3d(d.J0.row(child) - d.J0.row(j))
                                      : Eigen::Vector3d(d.J0.row(j) - d.J0.row(d.parents[j]));
    p.axis = axis.norm() > 1e-9 ? axis.normalized() : Eigen::Vector3d::UnitY();
    const int row = std::min(j, 23);
    const Limit& L = kLimits[row];
    for (int k = 0; k < 3; ++k) {
      p.lo(k) = L.lo[k] * kDeg;
      p.hi(k) = L.hi[k] * kDeg;
    }
    p.mean = stance.body_pose.segment<3>(3 * (j - 1));
    p.sigma_swing = kSigma[row][0] * kDeg;
    p.sigma_twist = kSigma[row][1] * kDeg;
    p.w_limits = w_limits;
  }
  return out;
}

}  // namespace ks::fit
