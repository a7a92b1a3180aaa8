#include "avatar/pose.hpp"

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

namespace {

Eigen::Matrix3d rodrigues(const Eigen::Vector3d& aa) {
  const double theta = aa.norm();
  if (theta < 1e-12) {
    // First order: I + [aa]x
    Eigen::Matrix3d K;
    K << 0, -aa.z(), aa.y(), aa.z(), 0, -aa.x(), -aa.y(), aa.x(), 0;
    return Eigen::Matrix3d::Identity() + K;
  }
  return Eigen::AngleAxisd(theta, aa / theta).toRotationMatrix();
}

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

// World transforms G_j (rotation, posed joint location) before translation.
void forward_kinematics(const Avatar& a, const Eigen::MatrixXd& pose,
                        std::vector<Eigen::Matrix3d>& Rw, std::vector<Eigen::Vector3d>& tw) {
  const int J = a.num_joints();
  Rw.resize(J);
  tw.resize(J);
  for (int j = 0; j < J; ++j) {
    const Eigen::Matrix3d Rl = rodrigues(pose.row(j).transpose());
    const Eigen::Vector3d Jj = a.rest_joints.row(j).transpose();
    const int par = a.parents[j];
    if (par < 0) {
      Rw[j] = Rl;
      tw[j] = Jj;
    } else {
      const Eigen::Vector3d rel = Jj - a.rest_joints.row(par).transpose();
      Rw[j] = Rw[par] * Rl;
      tw[j] = Rw[par] * rel + tw[par];
    }
  }
}

}  // namespace

std::vector<Eigen::Matrix4d> avatar_joint_transforms(const Avatar& a, const BodyParams& p) {
  const Eigen::MatrixXd pose = avatar_full_pose(a, p);
  std::vector<Eigen::Matrix3d> Rw;
  std::vector<Eigen::Vector3d> tw;
  forward_kinematics(a, pose, Rw, tw);
  std::vector<Eigen::Matrix4d> A(a.num_joints());
  for (int j = 0; j < a.num_joints(); ++j) {
    A[j].setIdentity();
    A[j].topLeftCorner<3, 3>() = Rw[j];
    A[j].topRightCorner<3, 1>() = tw[j] - Rw[j] * a.rest_joints.row(j).transpose() + p.transl;
  }
  return A;
}

Eigen::MatrixXd avatar_posed_joints(const Avatar& a, const BodyParams& p) {
  const Eigen::MatrixXd pose = avatar_full_pose(a, p);
  std::vector<Eigen::Matrix3d> Rw;
  std::vector<Eigen::Vector3d> tw;
  forward_kinematics(a, pose, Rw, tw);
  Eigen::MatrixXd out(a.num_joints(), 3);
  for (int j = 0; j < a.num_joints(); ++j) out.row(j) = (tw[j] + p.transl).transpose();
  return out;
}

void matrix_to_quat(const float m[9], float q[4]) {
  // m row-major. Shepperd: pick the largest of trace, m00, m11, m22 for stability.
  const float m00 = m[0], m01 = m[1], m02 = m[2];
  const float m10 = m[3], m11 = m[4], m12 = m[5];
  const float m20 = m[6], m21 = m[7], m22 = m[8];
  const float tr = m00 + m11 + m22;
  float w, x, y, z;
  if (tr > 0.f) {
    const float s = std::sqrt(tr + 1.f) * 2.f;
    w = 0.25f * s;
    x = (m21 - m12) / s;
    y = (m02 - m20) / s;
    z = (m10 - m01) / s;
  } else if (m00 > m11 && m00 > m22) {
    const float s = std::sqrt(std::max(1.f + m00 - m11 - m22, 1e-12f)) * 2.f;
    w = (m21 - m12) / s;
    x = 0.25f * s;
    y = (m01 + m10) / s;
    z = (m02 + m20) / s;
  } else if (m11 > m22) {
    const float s = std::sqrt(std::max(1.f + m11 - m00 - m22, 1e-12f)) * 2.f;
    w = (m02 - m20) / s;
    x = (m01 + m10) / s;
    y = 0.25f * s;
    z = (m12 + m21) / s;
  } else {
    const float s = std::sqrt(std::max(1.f + m22 - m00 - m11, 1e-12f)) * 2.f;
    w = (m10 - m01) / s;
    x = (m02 + m20) / s;
    y = (m12 + m21) / s;
    z = 0.25f * s;
  }
  const float n = std::sqrt(w * w + x * x + y * y + z * z);
  const float inv = n > 0.f ? 1.f / n : 0.f;
  q[0] = w * inv;
  q[1] = x * inv;
  q[2] = y * inv;
  q[3] = z * inv;
  if (n == 0.f) q[0] = 1.f;
}

namespace {

// Row-major 3x4 float transforms for the hot loop.
std::vector<float> pack_transforms(const std::vector<Eigen::Matrix4d>& A) {
  std::vector<float> T(A.size() * 12);
  for (size_t j = 0; j < A.size(); ++j)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) T[j * 12 + r * 4 + c] = float(A[j](r, c));
  return T;
}

inline void blend(const float* T, const int32_t* js, const float* ws, float M[12]) {
  for (int e = 0; e < 12; ++e) M[e] = 0.f;
  for (int k = 0; k < kAvatarSkinK; ++k) {
    const float w = ws[k];
    if (w == 0.f) continue;
    const float* A = T + size_t(js[k]) * 12;
    for (int e = 0; e < 12; ++e) M[e] += w * A[e];
  }
}

}  // namespace

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

void pose_avatar(const Avatar& a, const BodyParams& p, Gaussians& out, const BackfaceCull* cull) {
  const auto A = avatar_joint_transforms(a, p);
  const std::vector<float> T = pack_transforms(A);
  const Gaussians& g = a.gaussians;
  const long N = long(g.size());
  out.sh_degree = g.sh_degree;
  out.means.resize(g.means.size());
  out.quats.resize(g.quats.size());
  out.log_scales = g.log_scales;
  out.opacity_logits = g.opacity_logits;
  out.sh = g.sh;

  // Pose correctives: offsets = posedirs * feature, feature = (R_j - I) row-major, j >= 1.
  Eigen::VectorXf offsets;
  if (a.posedirs.size() > 0) {
    const Eigen::MatrixXd pose = avatar_full_pose(a, p);
    const int J = a.num_joints();
    Eigen::VectorXf feat(9 * (J - 1));
    for (int j = 1; j < J; ++j) {
      const Eigen::Matrix3d R = rodrigues(pose.row(j).transpose()) - Eigen::Matrix3d::Identity();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) feat[9 * (j - 1) + 3 * r + c] = float(R(r, c));
    }
    offsets = a.posedirs * feat;
  }
  const float* off = offsets.size() > 0 ? offsets.data() : nullptr;
  if (cull && !(cull->threshold >= 0.f))
    throw Error("pose_avatar: the back-face cull threshold must be in [0, 1]");
  const float* nrm =
      cull && cull->normals && cull->normals->size() == size_t(3 * N) && cull->threshold < 1.f
          ? cull->normals->data()
          : nullptr;
  const float ex = nrm ? float(cull->eye.x()) : 0.f, ey = nrm ? float(cull->eye.y()) : 0.f,
              ez = nrm ? float(cull->eye.z()) : 0.f, thr = nrm ? cull->threshold : 1.f;

#pragma omp parallel for schedule(static)
  for (long i = 0; i < N; ++i) {
    float M[12];
    blend(T.data(), &a.skin_joints[size_t(i) * kAvatarSkinK],
          &a.skin_weights[size_t(i) * kAvatarSkinK], M);
    float x = g.means[3 * i], y = g.means[3 * i + 1], z = g.means[3 * i + 2];
    if (off) {
      x += off[3 * i];
      y += off[3 * i + 1];
      z += off[3 * i + 2];
    }
    out.means[3 * i] = M[0] * x + M[1] * y + M[2] * z + M[3];
    out.means[3 * i + 1] = M[4] * x + M[5] * y + M[6] * z + M[7];
    out.means[3 * i + 2] = M[8] * x + M[9] * y + M[10] * z + M[11];
    if (nrm) {
      const float* n0 = nrm + 3 * i;
      const float nx = M[0] * n0[0] + M[1] * n0[1] + M[2] * n0[2];
      const float ny = M[4] * n0[0] + M[5] * n0[1] + M[6] * n0[2];
      const float nz = M[8] * n0[0] + M[9] * n0[1] + M[10] * n0[2];
      const float vx = out.means[3 * i] - ex, vy = out.means[3 * i + 1] - ey,
                  vz = out.means[3 * i + 2] - ez;
      const float d = nx * vx + ny * vy + nz * vz;
      // cos > thr without square roots (d > 0 is required first).
      if (d > 0.f &&
          d * d > thr * thr * (nx * nx + ny * ny + nz * nz) * (vx * vx + vy * vy + vz * vz))
        out.opacity_logits[i] = kCulledOpacityLogit;
    }
    const float R[9] = {M[0], M[1], M[2], M[4], M[5], M[6], M[8], M[9], M[10]};
    float qb[4];
    matrix_to_quat(R, qb);
    const float* q = &g.quats[4 * size_t(i)];
    // Normalise the Gaussian's own quaternion, then qb * q (Hamilton product).
    const float qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const float s = qn > 0.f ? 1.f / qn : 0.f;
    const float w2 = q[0] * s, x2 = q[1] * s, y2 = q[2] * s, z2 = q[3] * s;
    float* o = &out.quats[4 * size_t(i)];
    o[0] = qb[0] * w2 - qb[1] * x2 - qb[2] * y2 - qb[3] * z2;
    o[1] = qb[0] * x2 + qb[1] * w2 + qb[2] * z2 - qb[3] * y2;
    o[2] = qb[0] * y2 - qb[1] * z2 + qb[2] * w2 + qb[3] * x2;
    o[3] = qb[0] * z2 + qb[1] * y2 - qb[2] * x2 + qb[3] * w2;
  }
}

Gaussians pose_avatar(const Avatar& a, const BodyParams& p) {
  Gaussians out;
  pose_avatar(a, p, out);
  return out;
}

std::vector<float> skin_points(const Avatar& a, const std::vector<Eigen::Matrix4d>& transforms,
                               const std::vector<float>& pts) {
  if (pts.size() != a.anchors.size()) throw Error("skin_points: expected one point per Gaussian");
  const std::vector<float> T = pack_transforms(transforms);
  std::vector<float> out(pts.size());
  const long N = long(pts.size() / 3);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < N; ++i) {
    float M[12];
    blend(T.data(), &a.skin_joints[size_t(i) * kAvatarSkinK],
          &a.skin_weights[size_t(i) * kAvatarSkinK], M);
    const float x = pts[3 * i], y = pts[3 * i + 1], z = pts[3 * i + 2];
    for (int r = 0; r < 3; ++r)
      out[3 * i + r] = M[4 * r] * x + M[4 * r + 1] * y + M[4 * r + 2] * z + M[4 * r + 3];
  }
  return out;
}

}  // namespace ks

namespace ks {

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
  return BodyParams::from_json(j, m);
}

}  // namespace ks
