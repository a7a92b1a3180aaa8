// The rasterizer's forward projection for float, CW Gaussians at a time (the same steps as
// preprocess.cpp's per-Gaussian loop, which stays the double path of the tests): SSE2 blocks of 4
// on the portable build, AVX2 blocks of 8 chosen at run time. Both widths run the same
// operations in the same order (no contraction: the AVX2 target has no FMA), so every kernel
// choice renders the same images; against the per-Gaussian Eigen code the results agree to float
// rounding (the exponentials are the tile kernels' polynomial, the order of sums differs).
#pragma GCC diagnostic ignored "-Wpsabi"
#include <omp.h>

#include <algorithm>
#include <cmath>

#include "core/simd.hpp"
#include "raster/raster_internal.hpp"
#include "raster/sh.hpp"

namespace ks::raster {

namespace {

// The core lanes plus the tile kernels' exponential.
template <int CW>
struct Lanes : ks::Lanes<CW> {
  using Base = ks::Lanes<CW>;
  using V = typename Base::V;
  // exp for any x (clamped to [-87, 88]): the tile kernels' polynomial.
  [[gnu::always_inline]] static V exp(V x) {
    x = x > 88.0f ? Base::splat(88.0f) : x;
    return Simd<float, CW>::exp(x);
  }
};

// One block of CW Gaussians starting at i0 (n <= CW of them real; the rest are padding).
template <int CW>
[[gnu::always_inline]] inline void project_block(const Gaussians& g, const CameraT<float>& cam,
                                                 const RasterSettings& s, size_t i0, int n,
                                                 RasterResultT<float>& out) {
  using L = Lanes<CW>;
  using V = typename L::V;
  using I = typename L::I;
  const int deg = g.sh_degree, K = g.coeffs();
  // Gather the block (padding lanes repeat the first Gaussian, so that they compute finite
  // values; nothing of theirs is stored).
  V mx, my, mz, qw, qx, qy, qz, l0, l1, l2, lo;
  for (int l = 0; l < CW; ++l) {
    const size_t i = i0 + size_t(l < n ? l : 0);
    mx[l] = g.means[3 * i], my[l] = g.means[3 * i + 1], mz[l] = g.means[3 * i + 2];
    qw[l] = g.quats[4 * i], qx[l] = g.quats[4 * i + 1], qy[l] = g.quats[4 * i + 2],
    qz[l] = g.quats[4 * i + 3];
    l0[l] = g.log_scales[3 * i], l1[l] = g.log_scales[3 * i + 1], l2[l] = g.log_scales[3 * i + 2];
    lo[l] = g.opacity_logits[i];
  }
  const auto& R = cam.R;
  // World -> camera.
  const V px = R(0, 0) * mx + R(0, 1) * my + R(0, 2) * mz + cam.t[0];
  const V py = R(1, 0) * mx + R(1, 1) * my + R(1, 2) * mz + cam.t[1];
  const V pz = R(2, 0) * mx + R(2, 1) * my + R(2, 2) * mz + cam.t[2];
  I ok = pz >= s.near_plane;
  const V o = 1.0f / (1.0f + L::exp(-lo));
  ok &= o >= float(1.0 / 255.0);
  // 3D covariance S = M M^T, M = R(q / |q|) diag(exp(log_scale)).
  const V qn = L::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  ok &= qn > 1e-12f;
  const V w = qw / qn, x = qx / qn, y = qy / qn, z = qz / qn;
  const V s0 = L::exp(l0), s1 = L::exp(l1), s2 = L::exp(l2);
  const V M00 = (1 - 2 * (y * y + z * z)) * s0, M01 = (2 * (x * y - w * z)) * s1,
          M02 = (2 * (x * z + w * y)) * s2;
  const V M10 = (2 * (x * y + w * z)) * s0, M11 = (1 - 2 * (x * x + z * z)) * s1,
          M12 = (2 * (y * z - w * x)) * s2;
  const V M20 = (2 * (x * z - w * y)) * s0, M21 = (2 * (y * z + w * x)) * s1,
          M22 = (1 - 2 * (x * x + y * y)) * s2;
  const V S00 = M00 * M00 + M01 * M01 + M02 * M02, S01 = M00 * M10 + M01 * M11 + M02 * M12,
          S02 = M00 * M20 + M01 * M21 + M02 * M22, S11 = M10 * M10 + M11 * M11 + M12 * M12,
          S12 = M10 * M20 + M11 * M21 + M12 * M22, S22 = M20 * M20 + M21 * M21 + M22 * M22;
  // EWA: T = J R with the perspective Jacobian at the clamped x/z, y/z; S2 = T S T^T.
  const V ux = L::min(L::max(px / pz, L::splat(cam.lox)), L::splat(cam.hix));
  const V uy = L::min(L::max(py / pz, L::splat(cam.loy)), L::splat(cam.hiy));
  const V J00 = cam.fx / pz, J02 = -cam.fx * ux / pz, J11 = cam.fy / pz, J12 = -cam.fy * uy / pz;
  const V T00 = J00 * R(0, 0) + J02 * R(2, 0), T01 = J00 * R(0, 1) + J02 * R(2, 1),
          T02 = J00 * R(0, 2) + J02 * R(2, 2);
  const V T10 = J11 * R(1, 0) + J12 * R(2, 0), T11 = J11 * R(1, 1) + J12 * R(2, 1),
          T12 = J11 * R(1, 2) + J12 * R(2, 2);
  // (T S) rows, then the three entries of T S T^T.
  const V a0 = T00 * S00 + T01 * S01 + T02 * S02, a1 = T00 * S01 + T01 * S11 + T02 * S12,
          a2 = T00 * S02 + T01 * S12 + T02 * S22;
  const V b0 = T10 * S00 + T11 * S01 + T12 * S02, b1 = T10 * S01 + T11 * S11 + T12 * S12,
          b2 = T10 * S02 + T11 * S12 + T12 * S22;
  const float lp = s.low_pass;
  const V A = a0 * T00 + a1 * T01 + a2 * T02 + lp, B = a0 * T10 + a1 * T11 + a2 * T12,
          C = b0 * T10 + b1 * T11 + b2 * T12 + lp;
  const V det = A * C - B * B;
  ok &= det > 0.0f;
  const V u = cam.fx * px / pz + cam.cx, v = cam.fy * py / pz + cam.cy;
  // Pixel bounding box of the region where alpha >= 1/255 can hold (preprocess.cpp).
  V Lm;
  for (int l = 0; l < CW; ++l) Lm[l] = std::max(0.0f, std::log(255.0f * o[l]));
  const V ex = L::sqrt(2 * Lm * A) + 0.01f, ey = L::sqrt(2 * Lm * C) + 0.01f;
  const V fx0 = L::ceil(u - ex - 0.5f), fx1 = L::floor(u + ex - 0.5f);
  const V fy0 = L::ceil(v - ey - 0.5f), fy1 = L::floor(v + ey - 0.5f);
  const float Wm = float(cam.W - 1), Hm = float(cam.H - 1);
  ok &= (fx1 >= 0.0f) & (fy1 >= 0.0f) & (fx0 <= Wm) & (fy0 <= Hm) & (fx0 <= fx1) & (fy0 <= fy1);
  const V mid = 0.5f * (A + C);
  const V lam1 = mid + L::sqrt(L::max(L::splat(0.1f), mid * mid - det));
  const V rad = L::ceil(3.0f * L::sqrt(lam1));
  // View direction and colour.
  const V dx = mx - float(cam.centre[0]), dy = my - float(cam.centre[1]),
          dz = mz - float(cam.centre[2]);
  const V dist = L::sqrt(dx * dx + dy * dy + dz * dz);
  const I has = dist > 0.0f;
  const V ddx = L::sel(has, dx / dist, L::splat(0.f)), ddy = L::sel(has, dy / dist, L::splat(0.f)),
          ddz = L::sel(has, dz / dist, L::splat(1.f));
  V basis[16];
  sh::basis<V>(deg, ddx, ddy, ddz, basis);
  V rgb[3];
  for (int ch = 0; ch < 3; ++ch) {
    V c = L::splat(0.5f);
    for (int k = 0; k < K; ++k) {
      V coef;
      for (int l = 0; l < CW; ++l) coef[l] = g.sh[((i0 + size_t(l < n ? l : 0)) * K + k) * 3 + ch];
      c += basis[k] * coef;
    }
    rgb[ch] = c;
  }
  for (int l = 0; l < n; ++l) {
    const size_t i = i0 + size_t(l);
    if (!ok[l]) {
      out.radii[i] = 0;
      continue;
    }
    out.radii[i] = std::max(1, int(rad[l]));
    float* cv = &out.cov3d[6 * i];
    cv[0] = S00[l], cv[1] = S01[l], cv[2] = S02[l], cv[3] = S11[l], cv[4] = S12[l], cv[5] = S22[l];
    out.means2d[2 * i] = u[l], out.means2d[2 * i + 1] = v[l];
    float* cn = &out.conics[3 * i];
    cn[0] = C[l] / det[l], cn[1] = -B[l] / det[l], cn[2] = A[l] / det[l];
    out.depths[i] = pz[l];
    out.opacities[i] = o[l];
    float* rec = &out.records[size_t(kRec) * i];
    rec[0] = u[l], rec[1] = v[l], rec[2] = cn[0], rec[3] = cn[1], rec[4] = cn[2], rec[5] = o[l];
    for (int ch = 0; ch < 3; ++ch) {
      out.sh_clamped[3 * i + ch] = rgb[ch][l] < 0;
      rec[6 + ch] = std::max(rgb[ch][l], 0.0f);
    }
    rec[9] = pz[l];
    rec[10] = std::max(fx0[l], 0.0f), rec[11] = std::min(fx1[l], Wm);
    rec[12] = std::max(fy0[l], 0.0f), rec[13] = std::min(fy1[l], Hm);
    rec[14] = rec[15] = 0;
  }
}

// Gaussians [b, e) in blocks of CW.
template <int CW>
[[gnu::always_inline]] inline void project_range(const Gaussians& g, const CameraT<float>& cam,
                                                 const RasterSettings& s, size_t b, size_t e,
                                                 RasterResultT<float>& out) {
  for (size_t i0 = b; i0 < e; i0 += CW)
    project_block<CW>(g, cam, s, i0, int(std::min<size_t>(CW, e - i0)), out);
}

void project_range_sse2(const Gaussians& g, const CameraT<float>& cam, const RasterSettings& s,
                        size_t b, size_t e, RasterResultT<float>& out) {
  project_range<4>(g, cam, s, b, e, out);
}

// (The OpenMP loop stays outside: its outlined body would not inherit the target.)
__attribute__((target("avx2"), flatten)) void project_range_avx2(const Gaussians& g,
                                                                 const CameraT<float>& cam,
                                                                 const RasterSettings& s, size_t b,
                                                                 size_t e,
                                                                 RasterResultT<float>& out) {
  project_range<8>(g, cam, s, b, e, out);
}

}  // namespace

void preprocess_forward_simd(const Gaussians& g, const CameraT<float>& cam, const RasterSettings& s,
                             Isa isa, RasterResultT<float>& out) {
  constexpr size_t kChunk = 512;  // Gaussians a task (a multiple of both block widths)
  const size_t N = g.size();
  const long chunks = long((N + kChunk - 1) / kChunk);
#pragma omp parallel for schedule(static)
  for (long c = 0; c < chunks; ++c) {
    const size_t b = size_t(c) * kChunk, e = std::min(N, b + kChunk);
    if (isa == Isa::kBaseline)
      project_range_sse2(g, cam, s, b, e, out);
    else
      project_range_avx2(g, cam, s, b, e, out);
  }
}

}  // namespace ks::raster
