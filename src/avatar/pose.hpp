#pragma once
// Posing a trained avatar for playback, from the avatar file alone (no body model needed):
// forward kinematics on the stored skeleton (rest joints + parents), pose correctives when the
// avatar stores them, then linear blend skinning of the Gaussians' means and rotations.
#include <Eigen/Core>
#include <Eigen/StdVector>
#include <nlohmann/json.hpp>
#include <vector>

#include "avatar/avatar.hpp"
#include "body/body_model.hpp"
#include "body/lbs.hpp"
#include "body/posing.hpp"

namespace ks {

// All joints' axis-angles (J x 3) for the avatar's skeleton from BodyParams: global_orient, then
// body_pose, then for 52 joints (SMPL+H) the hands, for 55 (SMPL-X) jaw, eyes and hands. body_pose
// may be empty (rest), 69 values (SMPL / default: 23 joints), 63 (SMPL+H / SMPL-X: 21 joints) or 3
// per body joint of this skeleton; any other length is a ks::Error. Between the two SMPL layouts
// the first 21 joints are shared: an SMPL motion's 69 values drive an SMPL+H / SMPL-X avatar's 21
// body joints (SMPL's hand joints 22, 23 are dropped), 63 values leave an SMPL avatar's joints 22,
// 23 at rest (as AMASS's SMPL+H motions do), and a skeleton with fewer joints uses the first ones.
Eigen::MatrixXd avatar_full_pose(const Avatar& avatar, const BodyParams& params);

// Skinning transforms (rest -> posed, translation included), one 4x4 per joint: world transform
// of joint j composed with the inverse of its rest placement (SMPL's A_j).
std::vector<Eigen::Matrix4d> avatar_joint_transforms(const Avatar& avatar,
                                                     const BodyParams& params);
// Posed joint locations (J x 3).
Eigen::MatrixXd avatar_posed_joints(const Avatar& avatar, const BodyParams& params);

// Unit normals (3N) of the canonical template at the Gaussians' anchors (area-weighted vertex
// normals), or empty when the avatar's template is not one vertex per Gaussian at its anchor
// (then there is nothing to cull by).
std::vector<float> avatar_anchor_normals(const Avatar& avatar);

// What posing needs for one pose: the skinning transforms and, when the avatar stores pose
// correctives, their offsets (3N; empty otherwise).
struct AvatarPoseInputs {
  std::vector<Eigen::Matrix4d> transforms;
  Eigen::VectorXf offsets;
};
AvatarPoseInputs avatar_pose_inputs(const Avatar& avatar, const BodyParams& params);

// Poses the canonical Gaussians with the avatar's skeleton, pose correctives and skin weights:
// the training's LBS (body/lbs.hpp), with optional back-face culling. `out` is resized, its
// buffers reused; keep_unposed: `out` was posed from this avatar before, its scales and SH are
// kept (lbs_forward).
void pose_avatar(const Avatar& avatar, const BodyParams& params, Gaussians& out,
                 const BackfaceCull* cull = nullptr, bool keep_unposed = false);
Gaussians pose_avatar(const Avatar& avatar, const BodyParams& params);

// Posing with its backward, for registration (the Gaussians fixed, the pose learned): the
// forward keeps what the backward needs.
struct AvatarPoseState {
  Eigen::MatrixXd pose;  // J x 3 (avatar_full_pose)
  Eigen::Vector3d transl = Eigen::Vector3d::Zero();
  PosedSkeleton<double> skeleton;
  Eigen::VectorXf offsets;  // 3N pose correctives, or empty
  LbsCache cache;
};
// pose_avatar (no culling), keeping `state`.
void pose_avatar(const Avatar& avatar, const BodyParams& params, Gaussians& out,
                 AvatarPoseState& state);
// d loss / d (full pose, J x 3) and d loss / d transl from dmeans (3N) and dquats (4N) of the
// posed Gaussians, through LBS (body/lbs.hpp lbs_transforms_backward), the pose correctives'
// feature and forward kinematics (body/posing.hpp).
void pose_avatar_backward(const Avatar& avatar, const AvatarPoseState& state,
                          const std::vector<float>& dmeans, const std::vector<float>& dquats,
                          Eigen::MatrixXd& dpose, Eigen::Vector3d& dtransl);

// Pose parameters from the PARAMS.json layout (BodyParams::from_json) checked against the
// avatar's skeleton kind (no body-model file needed). The avatar's shape is fixed: 'betas' other
// than the avatar's own and a non-zero 'expression' are a ks::Error.
BodyParams avatar_params_from_json(const Avatar& avatar, const nlohmann::json& j);

}  // namespace ks
