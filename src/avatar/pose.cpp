#include "avatar/pose.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <utility>

#include "body/posing.hpp"
#include "core/error.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

namespace {

void put3(Eigen::MatrixXd& pose, int row, const Eigen::VectorXd& v, int from) {
  for (int k = 0; k < 3; ++k) pose(row, k) = (from + k < v.size()) ? v[from + k] : 0.0;
}

}  // namespace

Eigen::MatrixXd avatar_full_pose(const Avatar& avatar, const BodyParams& p) {
  const int J = avatar.num_joints();
  Eigen::MatrixXd pose = Eigen::MatrixXd::Zero(J, 3);
  pose.row(0) = p.global_orient.transpose();
  int body_joints = J - 1;
  if (J == 52 || J == 55) body_joints = 21;
  // Only the layouts that exist are mapped (see pose.hpp); any other length is a mistake upstream,
  // not something to pad or cut silently.
  const Eigen::Index n = p.body_pose.size();
  if (n != 0 && n != 63 && n != 69 && n != 3 * body_joints)
    throw Error("pose: body_pose has " + std::to_string(n) +
                " values; expected 69 (SMPL / default: 23 joints x 3), 63 (SMPL+H / SMPL-X: 21 "
                "joints x 3) or " +
                std::to_string(3 * body_joints) + " (this avatar's " + std::to_string(body_joints) +
                " body joints x 3)");
  for (int j = 0; j < body_joints; ++j) put3(pose, 1 + j, p.body_pose, 3 * j);
  int next = 1 + body_joints;
  if (J == 55) {
    pose.row(next++) = p.jaw_pose.transpose();
    pose.row(next++) = p.leye_pose.transpose();
    pose.row(next++) = p.reye_pose.transpose();
  }
  if (J == 52 || J == 55) {
    for (int j = 0; j < 15; ++j) put3(pose, next + j, p.left_hand_pose, 3 * j);
    for (int j = 0; j < 15; ++j) put3(pose, next + 15 + j, p.right_hand_pose, 3 * j);
  }
  if (!pose.allFinite()) throw Error("pose: non-finite pose parameters");
  return pose;
}

namespace {

PosedSkeleton<double> avatar_skeleton(const Avatar& a, const BodyParams& p) {
  return forward_kinematics<double>(a.parents, a.rest_joints, avatar_full_pose(a, p), p.transl);
}

}  // namespace

std::vector<Eigen::Matrix4d> avatar_joint_transforms(const Avatar& a, const BodyParams& p) {
  return avatar_skeleton(a, p).transforms;
}

Eigen::MatrixXd avatar_posed_joints(const Avatar& a, const BodyParams& p) {
  return avatar_skeleton(a, p).joints;
}

std::vector<float> avatar_anchor_normals(const Avatar& a) {
  const long N = a.num_gaussians();
  if (N == 0 || a.template_vertices.rows() != N || a.template_faces.rows() == 0 ||
      a.anchors.size() != size_t(3 * N))
    return {};
  for (long i = 0; i < N; ++i)
    for (int k = 0; k < 3; ++k)
      if (std::abs(a.template_vertices(i, k) - double(a.anchors[size_t(3 * i + k)])) > 1e-4)
        return {};
  const Eigen::MatrixXd n = vertex_normals(a.template_vertices, a.template_faces);
  std::vector<float> out(size_t(3 * N));
  for (long i = 0; i < N; ++i)
    for (int k = 0; k < 3; ++k) out[size_t(3 * i + k)] = float(n(i, k));
  return out;
}

AvatarPoseInputs avatar_pose_inputs(const Avatar& a, const BodyParams& p) {
  PosedSkeleton<double> sk = avatar_skeleton(a, p);
  AvatarPoseInputs in;
  // Pose correctives: offsets = posedirs * (R_j - I) of the joints j >= 1.
  if (a.posedirs.size() > 0) in.offsets = a.posedirs * pose_feature(sk.local).cast<float>();
  in.transforms = std::move(sk.transforms);
  return in;
}

void pose_avatar(const Avatar& a, const BodyParams& p, Gaussians& out, const BackfaceCull* cull,
                 bool keep_unposed) {
  const AvatarPoseInputs in = avatar_pose_inputs(a, p);
  lbs_forward(a.gaussians, in.offsets.size() > 0 ? in.offsets.data() : nullptr, a.skin_joints,
              a.skin_weights, in.transforms, out, nullptr, cull, keep_unposed);
}

Gaussians pose_avatar(const Avatar& a, const BodyParams& p) {
  Gaussians out;
  pose_avatar(a, p, out);
  return out;
}

void pose_avatar(const Avatar& a, const BodyParams& p, Gaussians& out, AvatarPoseState& st) {
  st.pose = avatar_full_pose(a, p);
  st.transl = p.transl;
  st.skeleton = forward_kinematics<double>(a.parents, a.rest_joints, st.pose, st.transl);
  if (a.posedirs.size() > 0)
    st.offsets = a.posedirs * pose_feature(st.skeleton.local).cast<float>();
  else
    st.offsets.resize(0);
  lbs_forward(a.gaussians, st.offsets.size() > 0 ? st.offsets.data() : nullptr, a.skin_joints,
              a.skin_weights, st.skeleton.transforms, out, &st.cache);
}

void pose_avatar_backward(const Avatar& a, const AvatarPoseState& st,
                          const std::vector<float>& dmeans, const std::vector<float>& dquats,
                          Eigen::MatrixXd& dpose, Eigen::Vector3d& dtransl) {
  const int J = a.num_joints();
  if (st.pose.rows() != J || int(st.skeleton.local.size()) != J)
    throw Error("pose_avatar_backward: the state is from another avatar");
  const bool correctives = st.offsets.size() > 0;
  std::vector<Eigen::Matrix<double, 3, 4>> dA;
  std::vector<float> doff;
  lbs_transforms_backward(a.gaussians, correctives ? st.offsets.data() : nullptr, a.skin_joints,
                          a.skin_weights, J, st.cache, dmeans, dquats, dA,
                          correctives ? &doff : nullptr);
  forward_kinematics_backward(a.parents, a.rest_joints, st.pose, st.skeleton, Eigen::MatrixXd(), dA,
                              &dpose, nullptr, &dtransl);
  if (!correctives) return;
  // offsets = posedirs f, f = (L_j - I) row-major for j >= 1: d L_j = d f's block, and each
  // joint's local rotation is Rodrigues of its own pose row.
  const Eigen::VectorXf df = a.posedirs.transpose() * Eigen::Map<const Eigen::VectorXf>(
                                                          doff.data(), Eigen::Index(doff.size()));
  for (int j = 1; j < J; ++j) {
    Eigen::Matrix3d dL;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) dL(r, c) = double(df[9 * (j - 1) + 3 * r + c]);
    dpose.row(j) +=
        axis_angle_to_matrix_backward<double>(Eigen::Vector3d(st.pose.row(j).transpose()), dL)
            .transpose();
  }
}

BodyParams avatar_params_from_json(const Avatar& avatar, const nlohmann::json& j) {
  BodyModel m;  // only the kind and counts are consulted by from_json
  const std::string& k = avatar.body_kind;
  m.kind = k == "smpl"    ? BodyKind::kSMPL
           : k == "smplh" ? BodyKind::kSMPLH
           : k == "smplx" ? BodyKind::kSMPLX
                          : BodyKind::kDefault;
  m.num_betas = int(std::max<Eigen::Index>(avatar.betas.size(), 300));
  m.num_expression = m.kind == BodyKind::kSMPLX ? 100 : 0;
  m.parents = avatar.parents;
  m.joint_names = avatar.joint_names;
  BodyParams p = BodyParams::from_json(j, m);
  // The avatar's shape was fixed when it was trained (its rest joints and template): betas are
  // accepted only as the avatar's own, and expressions (not stored in an avatar) not at all.
  const Eigen::Index nb =
      j.contains("betas") ? std::max(p.betas.size(), avatar.betas.size()) : Eigen::Index(0);
  for (Eigen::Index k = 0; k < nb; ++k) {
    const double given = k < p.betas.size() ? p.betas[k] : 0.0;
    const double own = k < avatar.betas.size() ? avatar.betas[k] : 0.0;
    if (std::abs(given - own) > 1e-6)
      throw Error("params: 'betas' differ from the avatar's own shape (beta " + std::to_string(k) +
                  ": " + std::to_string(given) + " given, " + std::to_string(own) +
                  " trained); an avatar cannot be reshaped: leave 'betas' out");
  }
  if (p.expression.size() > 0 && !p.expression.isZero(0))
    throw Error(
        "params: 'expression' is not used by avatar playback (an avatar stores no "
        "expression blend shapes); leave it out");
  p.betas = avatar.betas;
  return p;
}

}  // namespace ks
