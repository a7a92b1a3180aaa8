// The rasterizer's per-Gaussian passes (3DGS's preprocess in forward.cu / backward.cu): project
// every Gaussian before compositing, and after the backward tile pass take its summed
// screen-space gradients back to the raw parameters. Both are built from the forward / backward
// pairs of projection.hpp and sh.hpp; the backward reads the conic, opacity and colour clamps
// from the render records and recomputes the 3D covariance (cheaper than storing it). The float
// forward runs in blocks (preprocess_simd.cpp); the forward here is the double path of the tests.
#include <omp.h>

#include "raster/raster_internal.hpp"
#include "raster/sh.hpp"

namespace ks::raster {

template <class T>
void preprocess_forward(const GaussiansT<T>& g, const CameraT<T>& cam, const RasterSettings& s,
                        RasterResultT<T>& out) {
  const size_t N = g.size();
  const int W = cam.W, H = cam.H;
  const int deg = g.sh_degree;
  const int K = g.coeffs();
  const T lp = T(s.low_pass);
  const T near = T(s.near_plane);
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < N; ++i) {
    out.radii[i] = 0;
    const V3<T> m(g.means[3 * i], g.means[3 * i + 1], g.means[3 * i + 2]);
    const V3<T> p = world_to_camera(cam, m);
    const T z = p.z();
    if (!(z >= near)) continue;
    const T o = opacity_forward(g.opacity_logits[i]);
    if (!(o >= T(1.0 / 255.0))) continue;
    Cov3d<T> cov;
    if (!quat_scale_to_cov3d(&g.quats[4 * i], &g.log_scales[3 * i], cov)) continue;
    const M3<T>& S3 = cov.S;
    const M2<T> S2 = project_cov3d(ewa_jacobian(cam, p), S3);
    const T A = S2(0, 0) + lp, B = S2(0, 1), C = S2(1, 1) + lp;
    const T det = A * C - B * B;
    if (!(det > 0)) continue;
    const Eigen::Matrix<T, 2, 1> uv = project_mean(cam, p);
    const T u = uv.x(), v = uv.y();
    // Pixel bounding box of the region where alpha >= 1/255 can hold:
    // o exp(-d^T Q d / 2) >= 1/255  <=>  d^T Q d <= 2 ln(255 o); half-widths sqrt(2 ln(255 o) A).
    const T L = std::max(T(0), std::log(T(255) * o));
    const T ex = std::sqrt(2 * L * A) + T(0.01), ey = std::sqrt(2 * L * C) + T(0.01);
    const T fx0 = std::ceil(u - ex - T(0.5)), fx1 = std::floor(u + ex - T(0.5));
    const T fy0 = std::ceil(v - ey - T(0.5)), fy1 = std::floor(v + ey - T(0.5));
    if (!(fx1 >= 0 && fy1 >= 0 && fx0 <= T(W - 1) && fy0 <= T(H - 1))) continue;
    if (!(fx0 <= fx1 && fy0 <= fy1)) continue;
    // The render record (the layout of RasterResultT::packed), written as it is computed.
    T* rec = &out.records[kRec * i];
    rec[10] = std::max(fx0, T(0));
    rec[11] = std::min(fx1, T(W - 1));
    rec[12] = std::max(fy0, T(0));
    rec[13] = std::min(fy1, T(H - 1));
    out.tile_rects[2 * i] = pack_tile_span(int(rec[10]), int(rec[11]));
    out.tile_rects[2 * i + 1] = pack_tile_span(int(rec[12]), int(rec[13]));
    const T mid = T(0.5) * (A + C);
    const T lam1 = mid + std::sqrt(std::max(T(0.1), mid * mid - det));
    out.radii[i] = std::max(1, int(std::ceil(3 * std::sqrt(lam1))));
    out.depths[i] = z;
    T conic[3];
    cov2d_to_conic(A, B, C, det, conic);
    // Colour from SH, view direction = mean - camera centre.
    T dist;
    const V3<T> dir = sh::view_direction(m, cam.centre, &dist);
    uint8_t clamped[3];
    sh::sh_to_color(deg, &g.sh[i * K * 3], dir, rec + 6, clamped);
    rec[0] = u, rec[1] = v;
    rec[2] = conic[0], rec[3] = conic[1], rec[4] = conic[2];
    rec[5] = o;
    rec[9] = z;
    rec[14] = T(clamped[0] + 2 * clamped[1] + 4 * clamped[2]);  // the backward's clamp bits
    rec[15] = 0;
  }
}

template <class T>
void preprocess_backward(const GaussiansT<T>& g, const CameraT<T>& cam, const RasterResultT<T>& fwd,
                         int threads, RasterGradsT<T>& gr) {
  const size_t N = g.size();
  const int deg = g.sh_degree;
  const int K = g.coeffs();
  const size_t stride = size_t(kNG) * N;
  size_param_grads(gr, N, K);
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < N; ++i) {
    // Screen-space gradients summed over the threads' buffers: mean2d (2), conic (3), opacity,
    // rgb (3).
    T gs[kNG] = {0};
    for (int th = 0; th < threads; ++th) {
      const T* a = gr.scratch.data() + size_t(th) * stride + size_t(kNG) * i;
      for (int q = 0; q < kNG; ++q) gs[q] += a[q];
    }
    for (int q = 0; q < 3; ++q) gr.means[3 * i + q] = 0, gr.log_scales[3 * i + q] = 0;
    for (int q = 0; q < 4; ++q) gr.quats[4 * i + q] = 0;
    for (int q = 0; q < 3 * K; ++q) gr.sh[i * 3 * K + q] = 0;
    gr.opacity_logits[i] = 0;
    gr.means2d[2 * i] = gs[0];
    gr.means2d[2 * i + 1] = gs[1];
    if (fwd.radii[i] == 0) continue;
    // The forward's state: the render record (conic, opacity, clamp bits) and the 3D
    // covariance, recomputed.
    const T* rec = &fwd.packed[size_t(kRec) * i];
    gr.opacity_logits[i] = opacity_backward(rec[5], gs[5]);
    const V3<T> m(g.means[3 * i], g.means[3 * i + 1], g.means[3 * i + 2]);
    // Colour -> SH coefficients and the view direction.
    V3<T> gmean = V3<T>::Zero();
    T dist;
    const V3<T> dir = sh::view_direction(m, cam.centre, &dist);
    const int bits = int(rec[14]);
    const uint8_t clamped[3] = {uint8_t(bits & 1), uint8_t(bits >> 1 & 1), uint8_t(bits >> 2 & 1)};
    sh::sh_to_color_backward(deg, &g.sh[i * K * 3], dir, dist, clamped, &gs[6], &gr.sh[i * K * 3],
                             gmean);
    // Conic -> 2D covariance -> 3D covariance and the camera-space mean; the 2D mean.
    const V3<T> p = world_to_camera(cam, m);
    Cov3d<T> cov;
    quat_scale_to_cov3d(&g.quats[4 * i], &g.log_scales[3 * i], cov);
    const M3<T>& S3 = cov.S;
    const M2<T> dS2 = cov2d_to_conic_backward(rec + 2, &gs[2]);
    V3<T> gp = V3<T>::Zero();
    project_mean_backward(cam, p, &gs[0], gp);
    M3<T> dS3;
    project_cov3d_backward(cam, p, ewa_jacobian(cam, p), S3, dS2, dS3, gp);
    world_to_camera_backward(cam, gp, gmean);
    for (int q = 0; q < 3; ++q) gr.means[3 * i + q] = gmean[q];
    // 3D covariance -> scale and rotation.
    quat_scale_to_cov3d_backward(&g.quats[4 * i], &g.log_scales[3 * i], dS3, &gr.log_scales[3 * i],
                                 &gr.quats[4 * i]);
  }
}

template void preprocess_forward(const GaussiansT<double>&, const CameraT<double>&,
                                 const RasterSettings&, RasterResultT<double>&);
template void preprocess_backward(const GaussiansT<float>&, const CameraT<float>&,
                                  const RasterResultT<float>&, int, RasterGradsT<float>&);
template void preprocess_backward(const GaussiansT<double>&, const CameraT<double>&,
                                  const RasterResultT<double>&, int, RasterGradsT<double>&);

}  // namespace ks::raster
