#include "body/lbs.hpp"
#pragma GCC diagnostic ignored "-Wpsabi"

#include <omp.h>
#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>

#include "core/error.hpp"
#include "core/parallel_copy.hpp"
#include "core/rotation.hpp"
#include "core/simd.hpp"

namespace ks {

// What one lbs_forward call (or LbsRanges pose) applies to every block.
struct LbsJob {
  const Gaussians* c;
  const float* pose_offsets;
  const int* joints;
  const float* weights;
  int K;
  const float* tf;  // 12 per joint: the skinning transforms' top 3 x 4, row-major, float
  // Gaussian i's posed mean, rotation and opacity logit go to index i - first of these.
  float *means, *quats, *opacity;
  size_t first;
  LbsCache* cache;
  const float* nrm;  // 3N anchor normals for culling, or nullptr
  float eye[3], thr;
};

namespace {

// Gaussians [i0, i0 + n) (n <= CW; the other lanes repeat the first and are not stored).
template <int CW>
[[gnu::always_inline]] inline void lbs_block(const LbsJob& job, size_t i0, int n) {
  using L = Lanes<CW>;
  using V = typename L::V;
  auto at = [&](int l) { return i0 + size_t(l < n ? l : 0); };
  using V4 = typename L::V4;
  // M = sum_k w_k A_{j_k}[0:3, :] (zero weights add nothing), each lane's rows as 4-float pieces
  // (a transform's 12 floats are contiguous), then turned into lanes.
  V4 rows[3][CW], qrows[CW];
  typedef float V8 __attribute__((vector_size(32)));
  for (int l = 0; l < CW; ++l) {
    const size_t i = at(l);
    V8 r01{};
    V4 r2{};
    const auto add = [&](size_t k) {
      const float w = job.weights[k];
      const float* T = job.tf + 12 * size_t(job.joints[k]);
      V8 t01;
      std::memcpy(&t01, T, sizeof t01);
      r01 += w * t01;
      r2 += w * L::load4(T + 8);
    };
    const size_t k0 = size_t(job.K) * i;
    if (job.K == 4) {
      add(k0), add(k0 + 1), add(k0 + 2), add(k0 + 3);
    } else {
      for (int q = 0; q < job.K; ++q) add(k0 + size_t(q));
    }
    rows[0][l] = __builtin_shufflevector(r01, r01, 0, 1, 2, 3);
    rows[1][l] = __builtin_shufflevector(r01, r01, 4, 5, 6, 7);
    rows[2][l] = r2;
    qrows[l] = L::load4(&job.c->quats[4 * i]);
  }
  V M[12], qc[4];
  for (int r = 0; r < 3; ++r) L::transpose4(rows[r], &M[4 * r]);
  L::transpose4(qrows, qc);
  // The means (plus pose offsets) as rows of four floats, then lanes (the fourth float is the
  // next Gaussian's, unused, unless the block holds the last Gaussian).
  V x[4];
  {
    const bool overread = i0 + size_t(CW) < job.c->size();
    V4 rm[CW];
    for (int l = 0; l < CW; ++l) {
      const size_t i = at(l);
      const float* p = &job.c->means[3 * i];
      const float* d = job.pose_offsets ? &job.pose_offsets[3 * i] : nullptr;
      if (overread) {
        rm[l] = L::load4(p);
        if (d) rm[l] += L::load4(d);
      } else {
        rm[l] = d ? V4{p[0] + d[0], p[1] + d[1], p[2] + d[2], 0.f} : V4{p[0], p[1], p[2], 0.f};
      }
    }
    L::transpose4(rm, x);
  }
  V m[3];
  for (int r = 0; r < 3; ++r)
    m[r] = M[4 * r] * x[0] + M[4 * r + 1] * x[1] + M[4 * r + 2] * x[2] + M[4 * r + 3];
  const V R[9] = {M[0], M[1], M[2], M[4], M[5], M[6], M[8], M[9], M[10]};
  V qb[4], qp[4];
  matrix_to_quat<L>(R, qb);
  quat_mul(qb, qc, qp);
  typename L::I culled{};
  if (job.nrm) {
    auto normal = [&](int k) {
      V v{};
      for (int l = 0; l < CW; ++l) v[l] = job.nrm[3 * at(l) + size_t(k)];
      return v;
    };
    const V n0[3] = {normal(0), normal(1), normal(2)};
    const V nx = M[0] * n0[0] + M[1] * n0[1] + M[2] * n0[2];
    const V ny = M[4] * n0[0] + M[5] * n0[1] + M[6] * n0[2];
    const V nz = M[8] * n0[0] + M[9] * n0[1] + M[10] * n0[2];
    const V vx = m[0] - job.eye[0], vy = m[1] - job.eye[1], vz = m[2] - job.eye[2];
    const V d = nx * vx + ny * vy + nz * vz;
    // cos > thr without square roots (d > 0 is required first).
    culled = (d > 0.f) & (d * d > job.thr * job.thr * (nx * nx + ny * ny + nz * nz) *
                                      (vx * vx + vy * vy + vz * vz));
  }
  // Lanes back to rows: a Gaussian's mean and rotation by one 4-float store each (a mean's
  // fourth float is the next Gaussian's first, which overwrites it; the last mean by its three).
  const V mp[4] = {m[0], m[1], m[2], V{}};
  V4 mrow[CW], qrow[CW];
  L::untranspose4(mp, mrow);
  L::untranspose4(qp, qrow);
  const size_t o0 = i0 - job.first;
  for (int l = 0; l < n; ++l) {
    const size_t o = o0 + size_t(l);
    if (l + 1 < n)
      std::memcpy(&job.means[3 * o], &mrow[l], sizeof(V4));
    else
      for (int k = 0; k < 3; ++k) job.means[3 * o + k] = mrow[l][k];
    std::memcpy(&job.quats[4 * o], &qrow[l], sizeof(V4));
  }
  if (n == CW) {
    const V op = L::sel(culled, L::splat(kCulledOpacityLogit), L::load(&job.c->opacity_logits[i0]));
    std::memcpy(&job.opacity[o0], &op, sizeof(V));
  } else {
    for (int l = 0; l < n; ++l)
      job.opacity[o0 + size_t(l)] =
          culled[l] ? kCulledOpacityLogit : job.c->opacity_logits[i0 + size_t(l)];
  }
  if (job.cache) {
    for (int l = 0; l < n; ++l) {
      const size_t i = i0 + size_t(l);
      for (int e = 0; e < 12; ++e) job.cache->M[12 * i + size_t(e)] = M[e][l];
      for (int k = 0; k < 4; ++k) job.cache->qblend[4 * i + k] = qb[k][l];
    }
  }
}

template <int CW>
[[gnu::always_inline]] inline void lbs_range(const LbsJob& job, size_t b, size_t e) {
  for (size_t i0 = b; i0 < e; i0 += CW) lbs_block<CW>(job, i0, int(std::min<size_t>(CW, e - i0)));
}

void lbs_range_sse2(const LbsJob& job, size_t b, size_t e) {
  lbs_range<4>(job, b, e);
}

// (Called from inside the OpenMP loop: its outlined body would not inherit the target.)
__attribute__((target("avx2"), flatten)) void lbs_range_avx2(const LbsJob& job, size_t b,
                                                             size_t e) {
  lbs_range<8>(job, b, e);
}

std::atomic<bool> g_allow_avx2{true};

bool lbs_avx2() {
#if defined(__x86_64__)
  static const bool ok = __builtin_cpu_supports("avx2");
  return ok && g_allow_avx2.load(std::memory_order_relaxed);
#else
  return false;
#endif
}

}  // namespace

bool lbs_allow_avx2(bool allow) {
  return g_allow_avx2.exchange(allow);
}

namespace {

void check_skin(const Gaussians& c, const std::vector<int>& skin_joints,
                const std::vector<float>& skin_weights, int& K) {
  const size_t n = c.size();
  K = n > 0 ? int(skin_joints.size() / n) : 4;
  if (n > 0 &&
      (K < 1 || skin_joints.size() != size_t(K) * n || skin_weights.size() != skin_joints.size()))
    throw Error("lbs_forward: skin joints/weights must be K per Gaussian");
}

void throw_joint_out_of_range(const std::vector<int>& skin_joints, uint32_t J) {
  for (const int j : skin_joints)
    if (j < 0 || uint32_t(j) >= J)
      throw Error("lbs_forward: skin joint " + std::to_string(j) + " out of range (" +
                  std::to_string(J) + " transforms)");
}

void set_cull(const BackfaceCull* cull, size_t n, LbsJob& job) {
  if (cull && !(cull->threshold >= 0.f && cull->threshold <= 1.f))
    throw Error("lbs_forward: the back-face cull threshold must be in [0, 1]");
  job.nrm = nullptr;
  job.thr = 1.f;
  if (cull && cull->normals && cull->normals->size() == 3 * n && cull->threshold < 1.f) {
    job.nrm = cull->normals->data();
    for (int k = 0; k < 3; ++k) job.eye[k] = float(cull->eye[k]);
    job.thr = cull->threshold;
  }
}

void run_range(const LbsJob& job, size_t b, size_t e) {
  if (lbs_avx2())
    lbs_range_avx2(job, b, e);
  else
    lbs_range_sse2(job, b, e);
}

}  // namespace

void skin_transforms_3x4(const std::vector<Eigen::Matrix4d>& transforms, std::vector<float>& tf) {
  tf.resize(12 * transforms.size());
  for (size_t j = 0; j < transforms.size(); ++j)
    for (int r = 0; r < 3; ++r)
      for (int cc = 0; cc < 4; ++cc) tf[12 * j + size_t(4 * r + cc)] = float(transforms[j](r, cc));
}

void lbs_forward(const Gaussians& c, const float* pose_offsets, const std::vector<int>& skin_joints,
                 const std::vector<float>& skin_weights,
                 const std::vector<Eigen::Matrix4d>& transforms, Gaussians& posed, LbsCache* cache,
                 const BackfaceCull* cull, bool keep_unposed) {
  const long n = long(c.size());
  int K = 4;
  check_skin(c, skin_joints, skin_weights, K);
  LbsJob job{};
  set_cull(cull, size_t(n), job);
  posed.sh_degree = c.sh_degree;
  posed.means.resize(3 * size_t(n));
  posed.quats.resize(4 * size_t(n));
  if (!keep_unposed || posed.log_scales.size() != c.log_scales.size() ||
      posed.sh.size() != c.sh.size()) {
    parallel_assign(posed.log_scales, c.log_scales);
    parallel_assign(posed.sh, c.sh);
  }
  posed.opacity_logits.resize(size_t(n));  // written every call (culling)
  if (cache) {
    cache->M.resize(12 * size_t(n));
    cache->qblend.resize(4 * size_t(n));
  }
  std::vector<float> tf;
  skin_transforms_3x4(transforms, tf);
  job.c = &c;
  job.pose_offsets = pose_offsets;
  job.joints = skin_joints.data();
  job.weights = skin_weights.data();
  job.K = K;
  job.tf = tf.data();
  job.means = posed.means.data(), job.quats = posed.quats.data();
  job.opacity = posed.opacity_logits.data();
  job.first = 0;
  job.cache = cache;
  // Blocks of 4 (SSE2) or 8 (AVX2) Gaussians, the same operations at both widths.
  constexpr size_t kChunk = 512;
  const long chunks = long((size_t(n) + kChunk - 1) / kChunk);
  const uint32_t J = uint32_t(transforms.size());
  bool bad = false;
#pragma omp parallel for schedule(static) if (n > 1024) reduction(|| : bad)
  for (long ch = 0; ch < chunks; ++ch) {
    const size_t b = size_t(ch) * kChunk, e = std::min(size_t(n), b + kChunk);
    // The chunk's joints in range before any is used: one branch-free pass (a negative index
    // wraps to a large one).
    uint32_t largest = 0;
    for (size_t q = size_t(K) * b; q < size_t(K) * e; ++q)
      largest = std::max(largest, uint32_t(skin_joints[q]));
    if (largest >= J) {
      bad = true;
      continue;
    }
    run_range(job, b, e);
  }
  if (bad) throw_joint_out_of_range(skin_joints, J);
}

LbsRanges::LbsRanges(const Gaussians& canonical, const std::vector<int>& skin_joints,
                     const std::vector<float>& skin_weights, int num_transforms)
    : job_(std::make_unique<LbsJob>()), J_(num_transforms) {
  int K = 4;
  check_skin(canonical, skin_joints, skin_weights, K);
  uint32_t largest = 0;
  for (const int j : skin_joints) largest = std::max(largest, uint32_t(j));
  if (!skin_joints.empty() && (num_transforms < 0 || largest >= uint32_t(num_transforms)))
    throw_joint_out_of_range(skin_joints, uint32_t(std::max(num_transforms, 0)));
  job_->c = &canonical;
  job_->joints = skin_joints.data();
  job_->weights = skin_weights.data();
  job_->K = K;
  job_->thr = 1.f;
}

LbsRanges::~LbsRanges() = default;

void LbsRanges::set_pose(const std::vector<Eigen::Matrix4d>& transforms, const float* pose_offsets,
                         const BackfaceCull* cull) {
  if (int(transforms.size()) != J_)
    throw Error("LbsRanges: " + std::to_string(transforms.size()) + " transforms for " +
                std::to_string(J_) + " joints");
  skin_transforms_3x4(transforms, tf_);
  job_->tf = tf_.data();
  job_->pose_offsets = pose_offsets;
  set_cull(cull, job_->c->size(), *job_);
}

void LbsRanges::pose(size_t b, size_t e, float* means, float* quats, float* opacity_logits) const {
  LbsJob job = *job_;
  job.means = means, job.quats = quats, job.opacity = opacity_logits;
  job.first = b;
  job.cache = nullptr;
  run_range(job, b, e);
}

void lbs_backward(const LbsCache& cache, const std::vector<float>& dmp,
                  const std::vector<float>& dqp, std::vector<float>& dmc, std::vector<float>& dqc) {
  const long n = long(cache.qblend.size() / 4);
  if (dmp.size() != 3 * size_t(n) || dqp.size() != 4 * size_t(n))
    throw Error("lbs_backward: gradients do not match the forward pass");
  dmc.resize(3 * size_t(n));
  dqc.resize(4 * size_t(n));
#pragma omp parallel for schedule(static) if (n > 1024)
  for (long i = 0; i < n; ++i) {
    const size_t u = size_t(i);
    const float* a = cache.M.data() + 12 * u;
    const float* g = dmp.data() + 3 * u;
    for (int k = 0; k < 3; ++k) dmc[3 * u + k] = a[k] * g[0] + a[4 + k] * g[1] + a[8 + k] * g[2];
    // out = qb * q = L(qb) q with L(qb) orthogonal (|qb| = 1): dq = L(qb)^T dout = conj(qb) * dout.
    const float* qb = cache.qblend.data() + 4 * u;
    const float conj[4] = {qb[0], -qb[1], -qb[2], -qb[3]};
    quat_mul(conj, dqp.data() + 4 * u, dqc.data() + 4 * u);
  }
}

void lbs_transforms_backward(const Gaussians& c, const float* pose_offsets,
                             const std::vector<int>& skin_joints,
                             const std::vector<float>& skin_weights, int J, const LbsCache& cache,
                             const std::vector<float>& dmp, const std::vector<float>& dqp,
                             std::vector<Eigen::Matrix<double, 3, 4>>& dA,
                             std::vector<float>* doffsets) {
  const long n = long(c.size());
  int K = 4;
  check_skin(c, skin_joints, skin_weights, K);
  if (cache.M.size() != 12 * size_t(n) || cache.qblend.size() != 4 * size_t(n) ||
      dmp.size() != 3 * size_t(n) || dqp.size() != 4 * size_t(n))
    throw Error("lbs_transforms_backward: gradients do not match the forward pass");
  if (J <= 0) throw Error("lbs_transforms_backward: no joints");
  for (const int j : skin_joints)
    if (j < 0 || j >= J) throw_joint_out_of_range(skin_joints, uint32_t(J));
  if (doffsets) doffsets->resize(3 * size_t(n));
  using M34 = Eigen::Matrix<double, 3, 4>;
  // Per-thread sums added in thread order afterwards (the same result on every run).
  const bool par = n > 1024;
  std::vector<std::vector<M34>> sums(size_t(par ? omp_get_max_threads() : 1));
#pragma omp parallel if (par)
  {
    std::vector<M34>& acc = sums[size_t(omp_get_thread_num())];
    acc.assign(size_t(J), M34::Zero());
#pragma omp for schedule(static)
    for (long i = 0; i < n; ++i) {
      const size_t u = size_t(i);
      const float* a = cache.M.data() + 12 * u;
      const float* g = dmp.data() + 3 * u;
      double x[3];
      for (int k = 0; k < 3; ++k)
        x[k] = double(c.means[3 * u + k]) + (pose_offsets ? double(pose_offsets[3 * u + k]) : 0.0);
      M34 dM;
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) dM(r, k) = double(g[r]) * x[k];
        dM(r, 3) = double(g[r]);
      }
      if (doffsets)
        for (int k = 0; k < 3; ++k)
          (*doffsets)[3 * u + k] = a[k] * g[0] + a[4 + k] * g[1] + a[8 + k] * g[2];
      // q' = qb * q: column e of d q' / d qb is e_e * q.
      const float* qc = c.quats.data() + 4 * u;
      const float* dq = dqp.data() + 4 * u;
      double dqb[4] = {0, 0, 0, 0};
      if (dq[0] != 0.f || dq[1] != 0.f || dq[2] != 0.f || dq[3] != 0.f) {
        const double q[4] = {qc[0], qc[1], qc[2], qc[3]};
        for (int e = 0; e < 4; ++e) {
          double basis[4] = {0, 0, 0, 0}, col[4];
          basis[e] = 1;
          quat_mul(basis, q, col);
          for (int k = 0; k < 4; ++k) dqb[e] += col[k] * double(dq[k]);
        }
        const double m9[9] = {a[0], a[1], a[2], a[4], a[5], a[6], a[8], a[9], a[10]};
        double dm9[9];
        matrix_to_quat_backward(m9, dqb, dm9);
        for (int e = 0; e < 9; ++e) dM(e / 3, e % 3) += dm9[e];
      }
      for (int q = 0; q < K; ++q) {
        const float w = skin_weights[size_t(K) * u + size_t(q)];
        if (w == 0.f) continue;
        acc[size_t(skin_joints[size_t(K) * u + size_t(q)])] += double(w) * dM;
      }
    }
  }
  dA.assign(size_t(J), M34::Zero());
  for (const auto& acc : sums)
    for (size_t j = 0; j < acc.size(); ++j) dA[j] += acc[j];
}

Eigen::MatrixXd skin_points(const Eigen::MatrixXd& P, const Eigen::MatrixXd* offsets,
                            const SkinJoints& joints, const SkinWeights& weights,
                            const std::vector<Eigen::Matrix4d>& transforms) {
  const long N = long(P.rows());
  if (P.cols() != 3 || joints.rows() != N || weights.rows() != N || weights.cols() != joints.cols())
    throw Error("skin_points: points, joints and weights must have the same rows");
  const int K = int(joints.cols());
  Eigen::MatrixXd out(N, 3);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < N; ++i) {
    const Eigen::Matrix<double, 3, 4> M =
        blend_skin_transform(transforms, joints.row(i).data(), weights.row(i).data(), K);
    Eigen::Vector3d x = P.row(i).transpose();
    if (offsets && i < offsets->rows()) x += offsets->row(i).transpose();
    out.row(i) = (M.leftCols<3>() * x + M.col(3)).transpose();
  }
  return out;
}

}  // namespace ks
