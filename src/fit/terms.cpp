#include "fit/terms.hpp"

#include <algorithm>
#include <cmath>

#include "body/joints.hpp"
#include "fit/residuals.hpp"

namespace ks::fit {

namespace {
constexpr double kDeg = M_PI / 180.0;
namespace sj = smpl_joint;
}  // namespace

double keypoint_group_weight(int k, const FitOptions& o) {
  using namespace body25;
  if (k == kNose || (k >= kREye && k <= kLEar)) return o.w_face;
  if (k >= kLBigToe) return o.w_feet;
  return 1.0;
}

bool is_torso_keypoint(int k) {
  using namespace body25;
  return k == kNeck || k == kLShoulder || k == kRShoulder || k == kMidHip || k == kLHip ||
         k == kRHip;
}

double person_height_px(const FitInput& in) {
  double ymin = 1e18, ymax = -1e18;
  if (!in.mask.empty()) {
    for (int y = 0; y < in.height; ++y)
      for (int x = 0; x < in.width; ++x)
        if (in.mask.at(x, y, 0) >= 0.5f) {
          ymin = std::min(ymin, double(y));
          ymax = std::max(ymax, double(y + 1));
        }
  }
  if (!(ymax > ymin)) {
    for (const auto& k : in.keypoints)
      if (k.z() > 0) {
        ymin = std::min(ymin, k.y());
        ymax = std::max(ymax, k.y());
      }
    ymax = ymin + 1.15 * (ymax - ymin);
  }
  return std::max(10.0, ymax - ymin);
}

void add_frame_terms(ceres::Problem& problem, const FrameTerms& f, const FitOptions& o,
                     const FitStage& s, double* x, TermBlocks& groups) {
  const Layout& L = f.d.layout;
  const int P = L.size;
  for (int k = 0; k < kBody25Count; ++k) {
    const Eigen::Vector3d& kp = f.in.keypoints[size_t(k)];
    if (!(kp.z() > 0) || (s.torso_only && !is_torso_keypoint(k))) continue;
    const double w = o.w_keypoints * keypoint_group_weight(k, o) * kp.z();
    auto* loss =
        new ceres::ScaledLoss(new ceres::CauchyLoss(o.keypoint_robust), w, ceres::TAKE_OWNERSHIP);
    groups["keypoints"].push_back(problem.AddResidualBlock(
        new KeypointResidual(f.ev, f.pr, k, kp.head<2>(), f.unit, P), loss, x));
  }
  if (s.free_pose) {
    for (int j = 1; j <= L.pose_joints; ++j) {
      JointPrior jp = f.priors[size_t(j - 1)];
      jp.w_stance = s.prior_scale * o.w_pose_prior;
      groups["pose_prior"].push_back(
          problem.AddResidualBlock(new PoseResidual(jp, L.pose + 3 * (j - 1), P), nullptr, x));
      groups["joint_limits"].push_back(
          problem.AddResidualBlock(new LimitResidual(jp, L.pose + 3 * (j - 1), P), nullptr, x));
    }
    for (int j : {sj::kLeftElbow, sj::kRightElbow, sj::kLeftWrist, sj::kRightWrist})
      groups["arms_torso"].push_back(problem.AddResidualBlock(
          new ArmTorsoResidual(f.ev, j, 0.10, o.w_arm_torso, P), nullptr, x));
  }
  if (o.w_upright > 0 && !s.torso_only)
    groups["upright"].push_back(problem.AddResidualBlock(
        new UprightResidual(L.orient, o.upright_sigma_degrees * kDeg, o.w_upright, P), nullptr, x));
  if (o.w_ground > 0 && s.free_pose)
    groups["ground"].push_back(
        problem.AddResidualBlock(new GroundResidual(f.ev, sj::kLeftAnkle, sj::kRightAnkle, P),
                                 new ceres::ScaledLoss(new ceres::CauchyLoss(o.ground_robust_cm),
                                                       o.w_ground, ceres::TAKE_OWNERSHIP),
                                 x));
  if (s.free_betas && L.num_betas > 0)
    groups["shape_prior"].push_back(problem.AddResidualBlock(
        new ShapeResidual(L.betas, L.num_betas, o.w_shape, P), nullptr, x));
}

}  // namespace ks::fit
