#pragma once
// The fit's pose prior without licensed weights, per body-pose joint: closeness to a natural
// stance (a Gaussian on the bone's swing and on the twist about it, with everyday deviations) and
// soft anatomical limits of the axis-angle components. The tables are SMPL's 24 joints; a model
// with more body-pose joints reuses the last row.
#include <Eigen/Core>
#include <vector>

#include "fit/fit_body.hpp"

namespace ks::fit {

struct JointPrior {
  Eigen::Vector3d axis;    // the bone's direction at rest (twist axis)
  Eigen::Vector3d mean;    // the natural stance's axis-angle
  double sigma_swing = 1;  // radians
  double sigma_twist = 1;
  Eigen::Vector3d lo, hi;  // limits of the axis-angle components (radians)
  double w_stance = 0, w_limits = 0;
};

// One prior per body-pose joint (joints 1..pose_joints, in order): the stance standing with the
// arms lowered `arm_down_degrees` from the T-pose, limits weighted `w_limits`, w_stance 0 (each
// fit stage sets its own).
std::vector<JointPrior> make_joint_priors(const BodyData& d, double arm_down_degrees,
                                          double w_limits);

}  // namespace ks::fit
