#include "reconstruct/lbs.hpp"

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.hpp"

namespace ks {

void lbs_forward(const Gaussians& c, const std::vector<float>& pose_offsets,
                 const std::vector<int>& skin_joints, const std::vector<float>& skin_weights,
                 const std::vector<Eigen::Matrix4d>& transforms, Gaussians& posed,
                 LbsCache& cache) {
  const int n = int(c.size());
  posed.sh_degree = c.sh_degree;
  posed.means.resize(3 * size_t(n));
  posed.quats.resize(4 * size_t(n));
  posed.log_scales = c.log_scales;
  posed.opacity_logits = c.opacity_logits;
  posed.sh = c.sh;
  cache.A.resize(12 * size_t(n));
  cache.qblend.resize(4 * size_t(n));
  const bool has_po = pose_offsets.size() == 3 * size_t(n);
  const int K = n > 0 ? int(skin_joints.size() / size_t(n)) : 4;
  if (n > 0 &&
      (K < 1 || skin_joints.size() != size_t(K) * n || skin_weights.size() != skin_joints.size()))
    throw Error("lbs_forward: skin joints/weights must be K per Gaussian");
#pragma omp parallel for schedule(static) if (n > 1024)
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix<double, 3, 4> A = Eigen::Matrix<double, 3, 4>::Zero();
    for (int k = 0; k < K; ++k) {
      const float w = skin_weights[size_t(K) * i + k];
      if (w == 0.f) continue;
      A += double(w) * transforms[size_t(skin_joints[size_t(K) * i + k])].topRows<3>();
    }
    float* a = cache.A.data() + 12 * size_t(i);
    for (int r = 0; r < 3; ++r)
      for (int cc = 0; cc < 4; ++cc) a[4 * r + cc] = float(A(r, cc));
    double x[3];
    for (int k = 0; k < 3; ++k)
      x[k] = c.means[3 * size_t(i) + k] + (has_po ? pose_offsets[3 * size_t(i) + k] : 0.f);
    for (int r = 0; r < 3; ++r)
      posed.means[3 * size_t(i) + r] =
          float(A(r, 0) * x[0] + A(r, 1) * x[1] + A(r, 2) * x[2] + A(r, 3));
    Eigen::Matrix3d R = A.leftCols<3>();
    Eigen::Quaterniond q(R);
    q.normalize();
    float* qb = cache.qblend.data() + 4 * size_t(i);
    qb[0] = float(q.w()), qb[1] = float(q.x()), qb[2] = float(q.y()), qb[3] = float(q.z());
    quat_mul(qb, c.quats.data() + 4 * size_t(i), posed.quats.data() + 4 * size_t(i));
  }
}

void lbs_backward(const LbsCache& cache, const std::vector<float>& dmp,
                  const std::vector<float>& dqp, std::vector<float>& dmc, std::vector<float>& dqc) {
  const int n = int(cache.qblend.size() / 4);
  dmc.resize(3 * size_t(n));
  dqc.resize(4 * size_t(n));
#pragma omp parallel for schedule(static) if (n > 1024)
  for (int i = 0; i < n; ++i) {
    const float* a = cache.A.data() + 12 * size_t(i);
    const float* g = dmp.data() + 3 * size_t(i);
    for (int k = 0; k < 3; ++k)
      dmc[3 * size_t(i) + k] = a[k] * g[0] + a[4 + k] * g[1] + a[8 + k] * g[2];
    // out = qb * q: out = L(qb) q with L(qb) orthogonal (|qb| = 1); dq = L(qb)^T dout =
    // conj(qb) * dout.
    const float* qb = cache.qblend.data() + 4 * size_t(i);
    const float conj[4] = {qb[0], -qb[1], -qb[2], -qb[3]};
    quat_mul(conj, dqp.data() + 4 * size_t(i), dqc.data() + 4 * size_t(i));
  }
}

}  // namespace ks
