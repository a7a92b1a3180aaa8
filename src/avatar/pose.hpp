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

namespace ks {

// All joints' axis-angles (J x 3) for the avatar's skeleton from BodyParams: global_orient, then
// body_pose (a shorter body_pose is zero-padded, a longer one truncated: an SMPL motion drives the
// 21 body joints of SMPL-H/SMPL-X), then for 52 joints (SMPL+H) the hands, for 55 (SMPL-X) jaw,
// eyes and hands.
Eigen::MatrixXd avatar_full_pose(const Avatar& avatar, const BodyParams& params);

// Skinning transforms (rest -> posed, translation included), one 4x4 per joint: world transform
// of joint j composed with the inverse of its rest placement (SMPL's A_j).
std::vector<Eigen::Matrix4d> avatar_joint_transforms(const Avatar& avatar,
                                                     const BodyParams& params);
// Posed joint locations (J x 3).
Eigen::MatrixXd avatar_posed_joints(const Avatar& avatar, const BodyParams& params);

// Back-face culling for playback (an approximation; `evaluate` never uses it). A Gaussian hangs
// on the template surface, so one whose anchor normal, posed with the same blended transform as
// its mean, points away from the camera (cos(normal, mean - eye) > `threshold`) is behind the
// body's front surface; `pose_avatar` then gives it an opacity logit of -100 and the rasterizer
// drops it before sorting, binning and compositing.
struct BackfaceCull {
  const std::vector<float>* normals = nullptr;  // avatar_anchor_normals(); empty: no culling
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  float threshold = 0.4f;  // cosine in [0, 1]; 1 culls nothing
};
constexpr float kCulledOpacityLogit = -100.f;

// Unit normals (3N) of the canonical template at the Gaussians' anchors (area-weighted vertex
// normals), or empty when the avatar's template is not one vertex per Gaussian at its anchor
// (then there is nothing to cull by).
std::vector<float> avatar_anchor_normals(const Avatar& avatar);

// Poses the canonical Gaussians: mean' = M (mean + pose offset), M = sum_k w_k A_{j_k};
// rotation' = polar-normalised rotation of M's 3x3 block times the Gaussian's rotation (as a
// quaternion). Scales, opacities and colours are copied (opacities of culled Gaussians set to
// kCulledOpacityLogit when `cull` is given). `out` is resized, its buffers reused. OpenMP over
// Gaussians.
void pose_avatar(const Avatar& avatar, const BodyParams& params, Gaussians& out,
                 const BackfaceCull* cull = nullptr);
Gaussians pose_avatar(const Avatar& avatar, const BodyParams& params);

// Skins arbitrary points (e.g. the anchors, 3N) with the avatar's skin weights and the given
// transforms (no pose correctives): the piece `pose_avatar` applies to means.
std::vector<float> skin_points(const Avatar& avatar, const std::vector<Eigen::Matrix4d>& transforms,
                               const std::vector<float>& points);

// Quaternion (w, x, y, z) of the rotation nearest to a 3x3 matrix that is close to a rotation
// (Shepperd's method on the matrix, then normalised). Used for blended LBS matrices.
void matrix_to_quat(const float m[9], float q[4]);

}  // namespace ks

namespace ks {

// Pose parameters from the PARAMS.json layout (BodyParams::from_json) checked against the
// avatar's skeleton kind (no body-model file needed).
BodyParams avatar_params_from_json(const Avatar& avatar, const nlohmann::json& j);

}  // namespace ks
