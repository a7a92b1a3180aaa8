// Linear blend skinning of Gaussians on the device (lbs_cuda.cuh): body/lbs.hpp's lbs_block and
// core/rotation.hpp's matrix_to_quat / quat_mul written out for one thread a Gaussian.
#include "raster_cuda/lbs_cuda.cuh"

namespace ks::cuda {

namespace {

// The unit quaternion (w, x, y, z) of a rotation matrix (row-major 3 x 3), by the case of
// matrix_to_quat: the trace when positive, else the largest diagonal entry (the first of ties).
__device__ inline void matrix_quat(const float* m, float* q) {
  const float m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5], m20 = m[6],
              m21 = m[7], m22 = m[8];
  const bool cw = m00 + m11 + m22 > 0.0f;
  const bool y_over_x = m11 > m00;
  const bool cz = !cw && (m22 > (y_over_x ? m11 : m00));
  const bool cy = !cw && !cz && y_over_x;
  const bool cx = !cw && !cz && !cy;
  const float s = cw   ? m00 + m11 + m22 + 1.f
                  : cx ? m00 - m11 - m22 + 1.f
                  : cy ? m11 - m22 - m00 + 1.f
                       : m22 - m00 - m11 + 1.f;
  const float r = sqrtf(s), h = 0.5f / r, big = 0.5f * r;
  const float a = m21 - m12, b = m02 - m20, c = m10 - m01, d = m10 + m01, e = m20 + m02,
              f = m21 + m12;
  const float w = cw ? big : (cx ? a : (cy ? b : c)) * h;
  const float x = cx ? big : (cw ? a : (cy ? d : e)) * h;
  const float y = cy ? big : (cw ? b : (cx ? d : f)) * h;
  const float z = cz ? big : (cw ? c : (cx ? e : f)) * h;
  const float n = sqrtf(w * w + x * x + y * y + z * z);
  q[0] = w / n, q[1] = x / n, q[2] = y / n, q[3] = z / n;
}

__device__ inline void quat_product(const float* a, const float* b, float* o) {
  o[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  o[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
  o[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
  o[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

__global__ void lbs_kernel(LbsArgs a) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= a.N) return;
  // M = sum_k w_k A_{j_k}[0:3, :]
  float M[12];
  for (int e = 0; e < 12; ++e) M[e] = 0.f;
  for (int k = 0; k < a.K; ++k) {
    const size_t s = size_t(a.K) * size_t(i) + size_t(k);
    const float w = a.weights[s];
    const float* T = a.transforms + 12 * a.joints[s];
    for (int e = 0; e < 12; ++e) M[e] += w * T[e];
  }
  float x[3];
  for (int k = 0; k < 3; ++k)
    x[k] = a.means[3 * size_t(i) + k] + (a.offsets ? a.offsets[3 * size_t(i) + k] : 0.f);
  float m[3];
  for (int r = 0; r < 3; ++r)
    m[r] = M[4 * r] * x[0] + M[4 * r + 1] * x[1] + M[4 * r + 2] * x[2] + M[4 * r + 3];
  const float R[9] = {M[0], M[1], M[2], M[4], M[5], M[6], M[8], M[9], M[10]};
  float qb[4], qc[4], qp[4];
  matrix_quat(R, qb);
  for (int k = 0; k < 4; ++k) qc[k] = a.quats[4 * size_t(i) + k];
  quat_product(qb, qc, qp);
  bool culled = false;
  if (a.normals) {
    const float* n0 = a.normals + 3 * size_t(i);
    const float nx = M[0] * n0[0] + M[1] * n0[1] + M[2] * n0[2];
    const float ny = M[4] * n0[0] + M[5] * n0[1] + M[6] * n0[2];
    const float nz = M[8] * n0[0] + M[9] * n0[1] + M[10] * n0[2];
    const float vx = m[0] - a.eye[0], vy = m[1] - a.eye[1], vz = m[2] - a.eye[2];
    const float d = nx * vx + ny * vy + nz * vz;
    // cos > threshold without square roots (d > 0 first), as on the CPU.
    culled = d > 0.f && d * d > a.threshold * a.threshold * (nx * nx + ny * ny + nz * nz) *
                                    (vx * vx + vy * vy + vz * vz);
  }
  for (int k = 0; k < 3; ++k) a.out_means[3 * size_t(i) + k] = m[k];
  for (int k = 0; k < 4; ++k) a.out_quats[4 * size_t(i) + k] = qp[k];
  a.out_logits[i] = culled ? a.culled_logit : a.logits[i];
}

}  // namespace

cudaError_t launch_lbs(const LbsArgs& a, cudaStream_t stream) {
  if (a.N <= 0) return cudaSuccess;
  constexpr int kThreads = 256;
  lbs_kernel<<<(a.N + kThreads - 1) / kThreads, kThreads, 0, stream>>>(a);
  return cudaGetLastError();
}

}  // namespace ks::cuda
