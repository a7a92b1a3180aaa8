#pragma once
// Linear blend skinning of canonical Gaussians (3DGS-avatar style). For Gaussian i with K (usually
// 4) skin weights w_ij over joints j (4x4 skinning transforms T_j, rest -> posed):
//   A_i = sum_j w_ij T_j            (blended 4x4)
//   mean'_i = A_i[:3,:3] (mean_i + pose_offset_i) + A_i[:3,3]
//   quat'_i = q(A_i) * quat_i       (q(A) = the quaternion of the blended 3x3, normalised)
//   log_scale'_i = log_scale_i      (the blended matrix is treated as a rotation)
// The blended transforms depend only on the pose and the (fixed) skin weights, so the backward
// pass is linear: dmean = A^T dmean', dquat = L(q(A))^T dquat'.
#include <Eigen/Core>
#include <vector>

#include "gaussians/gaussians.hpp"

namespace ks {

struct LbsCache {
  std::vector<float> A;       // 12 N: blended 3x4 (row-major)
  std::vector<float> qblend;  // 4 N: quaternion of the blended rotation (w, x, y, z)
};

// pose_offsets: 3N (may be empty: none). Copies opacity and SH unchanged into `posed`.
void lbs_forward(const Gaussians& canonical, const std::vector<float>& pose_offsets,
                 const std::vector<int>& skin_joints, const std::vector<float>& skin_weights,
                 const std::vector<Eigen::Matrix4d>& transforms, Gaussians& posed, LbsCache& cache);
// dmeans (3N), dquats (4N) of the posed Gaussians -> canonical (overwrites dmeans_c, dquats_c).
// Log-scales, opacities, SH gradients pass through unchanged (the caller reuses them).
void lbs_backward(const LbsCache& cache, const std::vector<float>& dmeans_posed,
                  const std::vector<float>& dquats_posed, std::vector<float>& dmeans_canonical,
                  std::vector<float>& dquats_canonical);

// Hamilton product a * b, quaternions (w, x, y, z).
inline void quat_mul(const float* a, const float* b, float* out) {
  out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
  out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
  out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

}  // namespace ks
