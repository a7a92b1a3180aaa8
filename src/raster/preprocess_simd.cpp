// The rasterizer's forward projection for float, CW Gaussians at a time (the same steps as
// preprocess.cpp's per-Gaussian loop, which stays the double path of the tests), and beside it
// its backward, the per-Gaussian chain rule (projection.hpp's pairs, the same order of steps):
// SSE2 blocks of 4 on the portable build, AVX2 blocks of 8 chosen at run time. Both widths run the
// same operations in the same order (no contraction: the AVX2 target has no FMA), so every kernel
// choice renders the same images; against the per-Gaussian Eigen code the results agree to float
// rounding (the exponentials are the tile kernels' polynomial, the order of sums differs).
#pragma GCC diagnostic ignored "-Wpsabi"
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <utility>

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

// Four floats into an output that the pass writes once and does not read back (the SH
// gradients, 192 bytes a Gaussian at degree 3): a non-temporal store where the address allows,
// so that the lines are not first read for ownership (the pass ends with a store fence).
template <class V4>
[[gnu::always_inline]] inline void store_once(float* p, const V4& v) {
  static_assert(sizeof(V4) == 16, "four floats");
#if defined(__SSE2__)
  if ((reinterpret_cast<uintptr_t>(p) & 15) == 0) {
    _mm_stream_ps(p, (__m128)v);
    return;
  }
#endif
  std::memcpy(p, &v, sizeof v);
}

// Fetches the SH coefficients of Gaussians [i, i + count) (clipped to the cloud) towards the
// cache ahead of their use: at degree 3 they are 192 bytes a Gaussian, the largest per-Gaussian
// read of the projection and of its backward, and the hardware's own prefetching leaves these
// loads waiting on memory (a third of the projection's samples sat on them).
[[gnu::always_inline]] inline void prefetch_sh(const Gaussians& g, size_t i, size_t count) {
  const size_t row = size_t(3) * size_t(g.coeffs());
  const size_t n = g.size();
  if (i >= n) return;
  const char* p = reinterpret_cast<const char*>(g.sh.data() + i * row);
  const size_t bytes = std::min(count, n - i) * row * sizeof(float);
  for (size_t o = 0; o < bytes; o += 64) __builtin_prefetch(p + o);
}

// The render records of Gaussians [i, i + count) fetched for writing (one line each): the
// projection writes each record as four 16-byte pieces, the first piece of every lane's record
// before the second, and the hardware's own prefetching left those stores waiting for their
// lines (in-process A/B: the projection x0.92 in playback, x0.95 on the bench scene; a whole
// playback frame x0.98, a whole training step on the bench scenes unchanged).
[[gnu::always_inline]] inline void prefetch_records(RasterResultT<float>& out, size_t i,
                                                    size_t count) {
  const size_t n = std::min(out.radii.size(), i + count);
  for (; i < n; ++i) __builtin_prefetch(&out.records[size_t(kRec) * i], 1);
}

// The SH coefficients of the block's Gaussians into lanes (lane l: Gaussian id(l); padding
// lanes repeat the first), coef[f] = coefficient f = 3k + channel of every lane, 4 at a time by
// 4 x 4 transposes (each Gaussian's 3K coefficients are contiguous); 3K must be a multiple of 4.
template <int CW, class Id>
[[gnu::always_inline]] inline void sh_to_lanes(const Gaussians& g, Id id, int K,
                                               typename Lanes<CW>::V* coef) {
  using L = Lanes<CW>;
  for (int f = 0; f < 3 * K; f += 4) {
    typename L::V4 rows[CW];
    for (int l = 0; l < CW; ++l) rows[l] = L::load4(&g.sh[id(l) * K * 3 + size_t(f)]);
    L::transpose4(rows, coef + f);
  }
}

// The unit view directions from the camera centre to the block's means (+Z where they coincide,
// has = 0 there) and their distances: sh::view_direction on lanes.
template <class L, class V = typename L::V, class I = typename L::I>
[[gnu::always_inline]] inline void view_directions(const CameraT<float>& cam, V mx, V my, V mz,
                                                   V& ddx, V& ddy, V& ddz, V& dist, I& has) {
  const V dx = mx - float(cam.centre[0]), dy = my - float(cam.centre[1]),
          dz = mz - float(cam.centre[2]);
  dist = L::sqrt(dx * dx + dy * dy + dz * dz);
  has = dist > 0.0f;
  ddx = L::sel(has, dx / dist, L::splat(0.f));
  ddy = L::sel(has, dy / dist, L::splat(0.f));
  ddz = L::sel(has, dz / dist, L::splat(1.f));
}

// The 3D covariance on lanes (quat_scale_to_cov3d): S = M M^T, M = R(q / |q|) diag(exp(s)),
// with the pieces the chain rule reuses (|q|, the unit quaternion, R's entries, the scales). The
// projection and the chain rule both call this, so the backward recomputes the forward's S bit
// for bit instead of storing it (a round trip through memory cost the forward more than this).
template <class L, class V = typename L::V>
struct CovLanes {
  V qn, w, x, y, z, R[3][3], sc[3], S00, S01, S02, S11, S12, S22;
  [[gnu::always_inline]] CovLanes(V qw, V qx, V qy, V qz, V l0, V l1, V l2) {
    qn = L::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
    w = qw / qn, x = qx / qn, y = qy / qn, z = qz / qn;
    sc[0] = L::exp(l0), sc[1] = L::exp(l1), sc[2] = L::exp(l2);
    R[0][0] = 1 - 2 * (y * y + z * z), R[0][1] = 2 * (x * y - w * z), R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z), R[1][1] = 1 - 2 * (x * x + z * z), R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y), R[2][1] = 2 * (y * z + w * x), R[2][2] = 1 - 2 * (x * x + y * y);
    V M[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) M[r][c] = R[r][c] * sc[c];
    S00 = M[0][0] * M[0][0] + M[0][1] * M[0][1] + M[0][2] * M[0][2];
    S01 = M[0][0] * M[1][0] + M[0][1] * M[1][1] + M[0][2] * M[1][2];
    S02 = M[0][0] * M[2][0] + M[0][1] * M[2][1] + M[0][2] * M[2][2];
    S11 = M[1][0] * M[1][0] + M[1][1] * M[1][1] + M[1][2] * M[1][2];
    S12 = M[1][0] * M[2][0] + M[1][1] * M[2][1] + M[1][2] * M[2][2];
    S22 = M[2][0] * M[2][0] + M[2][1] * M[2][1] + M[2][2] * M[2][2];
  }
};

// A block's means, log-scales and quaternions, one 4-float row a lane (the fourth float of a
// mean or log-scale unused), into lanes by 4 x 4 transposes.
template <class L, class V = typename L::V, class V4 = typename L::V4>
[[gnu::always_inline]] inline void params_to_lanes(const V4* rm, const V4* rs, const V4* rq, V& mx,
                                                   V& my, V& mz, V& l0, V& l1, V& l2, V& qw, V& qx,
                                                   V& qy, V& qz) {
  V t[4];
  L::transpose4(rm, t);
  mx = t[0], my = t[1], mz = t[2];
  L::transpose4(rs, t);
  l0 = t[0], l1 = t[1], l2 = t[2];
  L::transpose4(rq, t);
  qw = t[0], qx = t[1], qy = t[2], qz = t[3];
}

// Where the projection reads the means, rotations and opacity logits: Gaussian i's at index
// i - first of these (the Gaussians' own, first = 0, or a GaussianSource's chunk); the rest comes
// from the Gaussians by id. padded: a mean's three floats may be read as four everywhere.
struct PoseInputs {
  const float *means, *quats, *opacity;
  size_t first;
  bool padded;
};

// J[3 c + a] = sum over k >= 1 of coef[3 k + c] times the derivative of basis function k along
// axis a (bx, by, bz: sh::basis_grad), for the K = (deg + 1)^2 coefficients of a degree known
// at compile time: the derivatives that are zero for every direction (sh::kGradAxes) are left
// out, a quarter of the products at degree 3.
template <int K, class V>
[[gnu::always_inline]] inline void color_dir_derivs(const V* coef, const V* bx, const V* by,
                                                    const V* bz, V* J) {
  // (One channel at a time: its three sums stay in registers.)
  for (int ch = 0; ch < 3; ++ch) {
    V jx{}, jy{}, jz{};
    [&]<int... k>(std::integer_sequence<int, k...>) {
      const auto term = [&]<int kk>() {
        constexpr int ax = sh::kGradAxes[kk];
        const V c = coef[3 * kk + ch];
        if constexpr ((ax & 1) != 0) jx += c * bx[kk];
        if constexpr ((ax & 2) != 0) jy += c * by[kk];
        if constexpr ((ax & 4) != 0) jz += c * bz[kk];
      };
      (term.template operator()<k + 1>(), ...);
    }
    (std::make_integer_sequence<int, K - 1>{});
    J[3 * ch] = jx, J[3 * ch + 1] = jy, J[3 * ch + 2] = jz;
  }
}

// One block of CW Gaussians starting at i0 (n <= CW of them real; the rest are padding).
template <int CW>
[[gnu::always_inline]] inline void project_block(const Gaussians& g, const PoseInputs& in,
                                                 const CameraT<float>& cam, const RasterSettings& s,
                                                 size_t i0, int n, RasterResultT<float>& out) {
  using L = Lanes<CW>;
  using V = typename L::V;
  using I = typename L::I;
  const int deg = g.sh_degree, K = g.coeffs();
  // Gather the block (padding lanes repeat the first Gaussian, so that they compute finite
  // values; nothing of theirs is stored).
  using V4 = typename L::V4;
  V mx, my, mz, qw, qx, qy, qz, l0, l1, l2, lo;
  {
    // Four floats from each Gaussian's means and log-scales (the fourth is the next Gaussian's,
    // unused), unless the block holds the last Gaussian.
    const bool overread = i0 + size_t(n) < g.size();
    V4 rm[CW], rq[CW], rs[CW];
    for (int l = 0; l < CW; ++l) {
      const size_t i = i0 + size_t(l < n ? l : 0), k = i - in.first;
      rq[l] = L::load4(&in.quats[4 * k]);
      if (overread || in.padded)
        rm[l] = L::load4(&in.means[3 * k]);
      else
        rm[l] = V4{in.means[3 * k], in.means[3 * k + 1], in.means[3 * k + 2], 0.f};
      if (overread)
        rs[l] = L::load4(&g.log_scales[3 * i]);
      else
        rs[l] = V4{g.log_scales[3 * i], g.log_scales[3 * i + 1], g.log_scales[3 * i + 2], 0.f};
    }
    if (n == CW) {
      lo = L::load(&in.opacity[i0 - in.first]);
    } else {
      for (int l = 0; l < CW; ++l) lo[l] = in.opacity[i0 + size_t(l < n ? l : 0) - in.first];
    }
    params_to_lanes<L>(rm, rs, rq, mx, my, mz, l0, l1, l2, qw, qx, qy, qz);
  }
  const auto& R = cam.R;
  // World -> camera.
  const V px = R(0, 0) * mx + R(0, 1) * my + R(0, 2) * mz + cam.t[0];
  const V py = R(1, 0) * mx + R(1, 1) * my + R(1, 2) * mz + cam.t[1];
  const V pz = R(2, 0) * mx + R(2, 1) * my + R(2, 2) * mz + cam.t[2];
  I ok = pz >= s.near_plane;
  const V o = 1.0f / (1.0f + L::exp(-lo));
  ok &= o >= float(1.0 / 255.0);
  // 3D covariance.
  const CovLanes<L> cov(qw, qx, qy, qz, l0, l1, l2);
  ok &= cov.qn > 1e-12f;
  const V S00 = cov.S00, S01 = cov.S01, S02 = cov.S02, S11 = cov.S11, S12 = cov.S12, S22 = cov.S22;
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
  // (log_at_least_one: never below max(0, log(255 o)), so the box is never smaller than the
  // exact one and the images and gradients are the same; one vector operation instead of a
  // std::log call a lane: in-process A/B x0.92 of the projection, one thread and playback.)
  const V Lm = L::log_at_least_one(255.0f * o);
  const V ex = L::sqrt(2 * Lm * A) + 0.01f, ey = L::sqrt(2 * Lm * C) + 0.01f;
  const V fx0 = L::ceil(u - ex - 0.5f), fx1 = L::floor(u + ex - 0.5f);
  const V fy0 = L::ceil(v - ey - 0.5f), fy1 = L::floor(v + ey - 0.5f);
  const float Wm = float(cam.W - 1), Hm = float(cam.H - 1);
  ok &= (fx1 >= 0.0f) & (fy1 >= 0.0f) & (fx0 <= Wm) & (fy0 <= Hm) & (fx0 <= fx1) & (fy0 <= fy1);
  const V mid = 0.5f * (A + C);
  const V lam1 = mid + L::sqrt(L::max(L::splat(0.1f), mid * mid - det));
  const V rad = L::ceil(3.0f * L::sqrt(lam1));
  // View direction and colour.
  V ddx, ddy, ddz, dist;
  I has;
  view_directions<L>(cam, mx, my, mz, ddx, ddy, ddz, dist, has);
  V basis[16];
  sh::basis<V>(deg, ddx, ddy, ddz, basis);
  // The coefficients into lanes: by sh_to_lanes where 3K is a multiple of 4, else lane by lane.
  V coef[48];
  if ((3 * K) % 4 == 0) {
    sh_to_lanes<CW>(
        g, [&](int l) { return i0 + size_t(l < n ? l : 0); }, K, coef);
  } else {
    for (int f = 0; f < 3 * K; ++f)
      for (int l = 0; l < CW; ++l) coef[f][l] = g.sh[(i0 + size_t(l < n ? l : 0)) * K * 3 + f];
  }
  V rgb[3];
  for (int ch = 0; ch < 3; ++ch) {
    V c = L::splat(0.5f);
    for (int k = 0; k < K; ++k) c += basis[k] * coef[3 * k + ch];
    rgb[ch] = c;
  }
  if (!out.color_dirs.empty()) {
    // A full forward (degree > 0): the colour's derivatives along the view direction, for the
    // backward (RasterResultT::color_dirs), while the coefficients are in registers; stored
    // once per Gaussian, in order, by non-temporal stores (the backward reads them after the
    // compositing has long pushed them out of the cache).
    V J[kColorDirs];
    J[9] = J[10] = J[11] = V{};
    const auto derivs = [&]<int kDeg>() {
      V bx[16], by[16], bz[16];
      sh::basis_grad<V>(kDeg, ddx, ddy, ddz, bx, by, bz);
      color_dir_derivs<(kDeg + 1) * (kDeg + 1)>(coef, bx, by, bz, J);
    };
    if (deg == 1)
      derivs.template operator()<1>();
    else if (deg == 2)
      derivs.template operator()<2>();
    else
      derivs.template operator()<3>();
    V4 rows[kColorDirs / 4][CW];
    for (int f = 0; f < kColorDirs / 4; ++f) L::untranspose4(J + 4 * f, rows[f]);
    for (int l = 0; l < n; ++l)
      for (int f = 0; f < kColorDirs / 4; ++f)
        store_once(&out.color_dirs[size_t(kColorDirs) * (i0 + size_t(l)) + size_t(4 * f)],
                   rows[f][l]);
  }
  // The render records, 16 floats a Gaussian as four pieces of 4 (written for culled lanes too:
  // only visible Gaussians' records are read).
  const V cn0 = C / det, cn1 = -B / det, cn2 = A / det;
  const V zero = L::splat(0.f);
  const V x0 = L::max(fx0, zero), x1 = L::min(fx1, L::splat(Wm)), y0 = L::max(fy0, zero),
          y1 = L::min(fy1, L::splat(Hm));
  // The colour channels the clamp at zero cut (the backward's), as bits 1, 2, 4 of slot 14.
  const V clamp = L::sel(rgb[0] < 0.0f, L::splat(1.f), zero) +
                  L::sel(rgb[1] < 0.0f, L::splat(2.f), zero) +
                  L::sel(rgb[2] < 0.0f, L::splat(4.f), zero);
  const V piece[4][4] = {{u, v, cn0, cn1},
                         {cn2, o, L::max(rgb[0], zero), L::max(rgb[1], zero)},
                         {L::max(rgb[2], zero), pz, x0, x1},
                         {y0, y1, clamp, zero}};
  // The tiles the pixel rectangle touches, two words a Gaussian (pack_tile_span, lane-wise).
  auto tiles = [](V a) { return __builtin_convertvector(a, I) / kTS; };
  const I trx = tiles(x0) | tiles(x1) << 16, try_ = tiles(y0) | tiles(y1) << 16;
  for (int c = 0; c < 4; ++c) {
    V4 rows[CW];
    L::untranspose4(piece[c], rows);
    for (int l = 0; l < n; ++l)
      std::memcpy(&out.records[size_t(kRec) * (i0 + size_t(l)) + size_t(4 * c)], &rows[l],
                  sizeof(V4));
  }
  // Radii (0: culled), depths and tile rectangles; a whole block by vector stores (a culled
  // Gaussian's depth and rectangle are then written too, and never read).
  const I one = I{} + 1, ri = __builtin_convertvector(rad, I);
  const I radii = ok & (ri > one ? ri : one);
  if (n == CW) {
    std::memcpy(&out.radii[i0], &radii, sizeof radii);
    std::memcpy(&out.depths[i0], &pz, sizeof pz);
    I rects[2];
    if constexpr (CW == 4) {
      rects[0] = __builtin_shufflevector(trx, try_, 0, 4, 1, 5);
      rects[1] = __builtin_shufflevector(trx, try_, 2, 6, 3, 7);
    } else {
      rects[0] = __builtin_shufflevector(trx, try_, 0, 8, 1, 9, 2, 10, 3, 11);
      rects[1] = __builtin_shufflevector(trx, try_, 4, 12, 5, 13, 6, 14, 7, 15);
    }
    std::memcpy(&out.tile_rects[2 * i0], rects, sizeof rects);
    return;
  }
  for (int l = 0; l < n; ++l) {
    const size_t i = i0 + size_t(l);
    out.radii[i] = radii[l];
    if (!ok[l]) continue;
    out.depths[i] = pz[l];
    out.tile_rects[2 * i] = uint32_t(trx[l]), out.tile_rects[2 * i + 1] = uint32_t(try_[l]);
  }
}

// The chain rule of one block of CW visible Gaussians ids[0 .. n) (n <= CW real), from the
// summed screen-space gradients to the raw parameters (preprocess.cpp's preprocess_backward,
// lane-wise); backward_range writes the others' zero gradients.
template <int CW>
[[gnu::always_inline]] inline void backward_block(const Gaussians& g, const CameraT<float>& cam,
                                                  const RasterResultT<float>& fwd, int threads,
                                                  const size_t* ids, int n,
                                                  RasterGradsT<float>& gr) {
  using L = Lanes<CW>;
  using V = typename L::V;
  using V4 = typename L::V4;
  const int deg = g.sh_degree, K = g.coeffs();
  const size_t N = g.size(), stride = size_t(kNG) * N;
  // Screen-space gradients summed over the threads' buffers (in thread order, as the scalar
  // loop); the block's parameters and its render records (padding lanes repeat the first
  // Gaussian). The records give the conic, the opacity and the clamp bits; the 3D covariance is
  // recomputed as the projection computed it.
  V gs[kNG];
  for (int q = 0; q < kNG; ++q) gs[q] = V{};
  V mx, my, mz, qw, qx, qy, qz, l0, l1, l2, op, cn[3], keep[3];
  {
    V4 rm[CW], rq[CW], rs[CW], r0[CW], r1[CW], r3[CW], ga[CW], gb[CW];
    static_assert(kNG == 9, "the sums as two rows of 4 and one");
    for (int l = 0; l < CW; ++l) {
      const size_t i = ids[l < n ? l : 0];
      ga[l] = gb[l] = V4{};
      for (int th = 0; th < threads; ++th) {
        const float* a = gr.scratch.data() + size_t(th) * stride + size_t(kNG) * i;
        ga[l] += L::load4(a), gb[l] += L::load4(a + 4), gs[8][l] += a[8];
      }
      rq[l] = L::load4(&g.quats[4 * i]);
      if (i + 1 < N) {  // four floats of the means and log-scales (the fourth is unused)
        rm[l] = L::load4(&g.means[3 * i]), rs[l] = L::load4(&g.log_scales[3 * i]);
      } else {
        rm[l] = V4{g.means[3 * i], g.means[3 * i + 1], g.means[3 * i + 2], 0.f};
        rs[l] = V4{g.log_scales[3 * i], g.log_scales[3 * i + 1], g.log_scales[3 * i + 2], 0.f};
      }
      const float* rec = &fwd.packed[size_t(kRec) * i];
      r0[l] = L::load4(rec), r1[l] = L::load4(rec + 4), r3[l] = L::load4(rec + 12);
    }
    L::transpose4(ga, gs);
    L::transpose4(gb, gs + 4);
    params_to_lanes<L>(rm, rs, rq, mx, my, mz, l0, l1, l2, qw, qx, qy, qz);
    V t[4];
    L::transpose4(r0, t);
    cn[0] = t[2], cn[1] = t[3];
    L::transpose4(r1, t);
    cn[2] = t[0], op = t[1];
    L::transpose4(r3, t);
    const typename L::I bits = __builtin_convertvector(t[2], typename L::I);
    for (int c = 0; c < 3; ++c) keep[c] = L::sel((bits & (1 << c)) != 0, V{}, L::splat(1.f));
  }
  const CovLanes<L> cov(qw, qx, qy, qz, l0, l1, l2);
  const V S[6] = {cov.S00, cov.S01, cov.S02, cov.S11, cov.S12, cov.S22};
  // The 2D means take their screen gradient as it is.
  for (int l = 0; l < n; ++l) {
    const size_t i = ids[l];
    gr.means2d[2 * i] = gs[0][l], gr.means2d[2 * i + 1] = gs[1][l];
  }
  const auto& R = cam.R;
  const V dlogit = gs[5] * op * (1.0f - op);
  // Colour -> SH coefficients and the view direction (sh_to_color_backward).
  V ddx, ddy, ddz, dist;
  typename L::I has;
  view_directions<L>(cam, mx, my, mz, ddx, ddy, ddz, dist, has);
  const V gc0 = keep[0] * gs[6], gc1 = keep[1] * gs[7], gc2 = keep[2] * gs[8];
  V b[16];
  sh::basis<V>(deg, ddx, ddy, ddz, b);
  // With 3K a multiple of 4, each lane's 3K gradients and coefficients move between lanes and
  // rows by 4 x 4 transposes (as in the projection); the same products and sums.
  const bool rows4 = (3 * K) % 4 == 0;
  if (rows4) {
    V t[48];
    for (int k = 0; k < K; ++k)
      t[3 * k] = b[k] * gc0, t[3 * k + 1] = b[k] * gc1, t[3 * k + 2] = b[k] * gc2;
    // All rows first, then each Gaussian's 3K gradients stored in order: its non-temporal
    // stores fill one line after another, where storing piece by piece across the block's
    // Gaussians kept CW lines half-written at once, more than the core's write-combining
    // buffers hold (in-process A/B: this pass x0.79 on the OpenSplat scene, x0.82 on the
    // bench scene).
    V4 rows[12][CW];
    for (int f = 0; f < 3 * K; f += 4) L::untranspose4(t + f, rows[f / 4]);
    for (int l = 0; l < n; ++l)
      for (int f = 0; f < 3 * K; f += 4)
        store_once(&gr.sh[ids[l] * K * 3 + size_t(f)], rows[f / 4][l]);
  } else {
    for (int l = 0; l < n; ++l) {
      float* d = &gr.sh[ids[l] * K * 3];
      for (int k = 0; k < K; ++k)
        d[3 * k] = b[k][l] * gc0[l], d[3 * k + 1] = b[k][l] * gc1[l],
              d[3 * k + 2] = b[k][l] * gc2[l];
    }
  }
  V gmx = V{}, gmy = V{}, gmz = V{};
  if (deg > 0) {
    V gdx = V{}, gdy = V{}, gdz = V{};
    if (!fwd.color_dirs.empty()) {
      // The forward's colour derivatives along the view direction (RasterResultT::color_dirs):
      // three rows of 4 a Gaussian into lanes, and the direction's gradient from them.
      V4 rows[kColorDirs / 4][CW];
      for (int l = 0; l < CW; ++l) {
        const float* d = &fwd.color_dirs[size_t(kColorDirs) * ids[l < n ? l : 0]];
        for (int f = 0; f < kColorDirs / 4; ++f) rows[f][l] = L::load4(d + 4 * f);
      }
      V J[kColorDirs];
      for (int f = 0; f < kColorDirs / 4; ++f) L::transpose4(rows[f], J + 4 * f);
      gdx = J[0] * gc0 + J[3] * gc1 + J[6] * gc2;
      gdy = J[1] * gc0 + J[4] * gc1 + J[7] * gc2;
      gdz = J[2] * gc0 + J[5] * gc1 + J[8] * gc2;
    } else {
      V bx[16], by[16], bz[16];
      sh::basis_grad<V>(deg, ddx, ddy, ddz, bx, by, bz);
      V coef[48];
      if (rows4)
        sh_to_lanes<CW>(
            g, [&](int l) { return ids[l < n ? l : 0]; }, K, coef);
      for (int k = 1; k < K; ++k) {
        V c0, c1, c2;
        if (rows4) {
          c0 = coef[3 * k], c1 = coef[3 * k + 1], c2 = coef[3 * k + 2];
        } else {
          for (int l = 0; l < CW; ++l) {
            const float* c = &g.sh[(ids[l < n ? l : 0] * K + k) * 3];
            c0[l] = c[0], c1[l] = c[1], c2[l] = c[2];
          }
        }
        const V w = c0 * gc0 + c1 * gc1 + c2 * gc2;
        gdx += w * bx[k], gdy += w * by[k], gdz += w * bz[k];
      }
    }
    const V dd = ddx * gdx + ddy * gdy + ddz * gdz;
    gmx = L::sel(has, (gdx - ddx * dd) / dist, V{});
    gmy = L::sel(has, (gdy - ddy * dd) / dist, V{});
    gmz = L::sel(has, (gdz - ddz * dd) / dist, V{});
  }
  // Conic -> 2D covariance: dS2 = -Q G Q, G = [[da, db / 2], [db / 2, dc]].
  const V ga = gs[2], gb = 0.5f * gs[3], gcc = gs[4];
  const V QG00 = cn[0] * ga + cn[1] * gb, QG01 = cn[0] * gb + cn[1] * gcc;
  const V QG10 = cn[1] * ga + cn[2] * gb, QG11 = cn[1] * gb + cn[2] * gcc;
  const V D00 = -(QG00 * cn[0] + QG01 * cn[1]), D01 = -(QG00 * cn[1] + QG01 * cn[2]);
  const V D10 = -(QG10 * cn[0] + QG11 * cn[1]), D11 = -(QG10 * cn[1] + QG11 * cn[2]);
  // The camera-space mean; the 2D mean's gradient (project_mean_backward).
  const V px = R(0, 0) * mx + R(0, 1) * my + R(0, 2) * mz + cam.t[0];
  const V py = R(1, 0) * mx + R(1, 1) * my + R(1, 2) * mz + cam.t[1];
  const V pz = R(2, 0) * mx + R(2, 1) * my + R(2, 2) * mz + cam.t[2];
  const V iz = 1.0f / pz, iz2 = iz * iz;
  V gpx = gs[0] * cam.fx * iz, gpy = gs[1] * cam.fy * iz;
  V gpz = -gs[0] * cam.fx * px * iz2 - gs[1] * cam.fy * py * iz2;
  // EWA (project_cov3d_backward): T = J R; dS3 = T^T dS2 T; GT = 2 dS2 T S3; GJ = GT R^T.
  const V rx = px / pz, ry = py / pz;
  const V ux = L::min(L::max(rx, L::splat(cam.lox)), L::splat(cam.hix));
  const V uy = L::min(L::max(ry, L::splat(cam.loy)), L::splat(cam.hiy));
  const V J00 = cam.fx * iz, J02 = -cam.fx * ux * iz, J11 = cam.fy * iz, J12 = -cam.fy * uy * iz;
  V T0[3], T1[3];
  for (int c = 0; c < 3; ++c)
    T0[c] = J00 * R(0, c) + J02 * R(2, c), T1[c] = J11 * R(1, c) + J12 * R(2, c);
  // dS2 T (2 x 3), then dS3 = T^T (dS2 T).
  V E0[3], E1[3];
  for (int c = 0; c < 3; ++c) E0[c] = D00 * T0[c] + D01 * T1[c], E1[c] = D10 * T0[c] + D11 * T1[c];
  V dS[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) dS[r][c] = T0[r] * E0[c] + T1[r] * E1[c];
  // GT = 2 (dS2 T) S3.
  const V S3[3][3] = {{S[0], S[1], S[2]}, {S[1], S[3], S[4]}, {S[2], S[4], S[5]}};
  V G0[3], G1[3];
  for (int c = 0; c < 3; ++c) {
    G0[c] = 2.0f * (E0[0] * S3[0][c] + E0[1] * S3[1][c] + E0[2] * S3[2][c]);
    G1[c] = 2.0f * (E1[0] * S3[0][c] + E1[1] * S3[1][c] + E1[2] * S3[2][c]);
  }
  // GJ = GT R^T: only the entries the Jacobian has.
  const V GJ00 = G0[0] * R(0, 0) + G0[1] * R(0, 1) + G0[2] * R(0, 2);
  const V GJ02 = G0[0] * R(2, 0) + G0[1] * R(2, 1) + G0[2] * R(2, 2);
  const V GJ11 = G1[0] * R(1, 0) + G1[1] * R(1, 1) + G1[2] * R(1, 2);
  const V GJ12 = G1[0] * R(2, 0) + G1[1] * R(2, 1) + G1[2] * R(2, 2);
  gpz += -GJ00 * cam.fx * iz2 - GJ11 * cam.fy * iz2;
  gpz += GJ02 * cam.fx * ux * iz2 + GJ12 * cam.fy * uy * iz2;
  const auto inx = (rx > cam.lox) & (rx < cam.hix), iny = (ry > cam.loy) & (ry < cam.hiy);
  const V gux = L::sel(inx, -GJ02 * cam.fx * iz, V{}), guy = L::sel(iny, -GJ12 * cam.fy * iz, V{});
  gpx += gux * iz, gpz -= gux * px * iz2;
  gpy += guy * iz, gpz -= guy * py * iz2;
  // World -> camera: dm += R^T dp.
  gmx += R(0, 0) * gpx + R(1, 0) * gpy + R(2, 0) * gpz;
  gmy += R(0, 1) * gpx + R(1, 1) * gpy + R(2, 1) * gpz;
  gmz += R(0, 2) * gpx + R(1, 2) * gpy + R(2, 2) * gpz;
  // 3D covariance -> scale and rotation (quat_scale_to_cov3d_backward).
  const V &qn = cov.qn, &w = cov.w, &x = cov.x, &y = cov.y, &z = cov.z;
  const V(&sc)[3] = cov.sc;
  const V(&Rq)[3][3] = cov.R;
  V GR[3][3], dls[3];
  for (int c = 0; c < 3; ++c) {
    // GM(:, c) = 2 dS M(:, c), M(:, c) = Rq(:, c) sc[c].
    V gm[3];
    for (int r = 0; r < 3; ++r)
      gm[r] = 2.0f * (dS[r][0] * Rq[0][c] + dS[r][1] * Rq[1][c] + dS[r][2] * Rq[2][c]) * sc[c];
    for (int r = 0; r < 3; ++r) GR[r][c] = gm[r] * sc[c];
    dls[c] = (gm[0] * Rq[0][c] + gm[1] * Rq[1][c] + gm[2] * Rq[2][c]) * sc[c];
  }
  const V gw = 2 * (-z * GR[0][1] + y * GR[0][2] + z * GR[1][0] - x * GR[1][2] - y * GR[2][0] +
                    x * GR[2][1]);
  const V gx = 2 * (y * GR[0][1] + z * GR[0][2] + y * GR[1][0] - 2 * x * GR[1][1] - w * GR[1][2] +
                    z * GR[2][0] + w * GR[2][1] - 2 * x * GR[2][2]);
  const V gy = 2 * (-2 * y * GR[0][0] + x * GR[0][1] + w * GR[0][2] + x * GR[1][0] + z * GR[1][2] -
                    w * GR[2][0] + z * GR[2][1] - 2 * y * GR[2][2]);
  const V gz = 2 * (-2 * z * GR[0][0] - w * GR[0][1] + x * GR[0][2] + w * GR[1][0] -
                    2 * z * GR[1][1] + y * GR[1][2] + x * GR[2][0] + y * GR[2][1]);
  const V dotq = w * gw + x * gx + y * gy + z * gz;
  const V dqw = (gw - w * dotq) / qn, dqx = (gx - x * dotq) / qn, dqy = (gy - y * dotq) / qn,
          dqz = (gz - z * dotq) / qn;
  for (int l = 0; l < n; ++l) {
    const size_t i = ids[l];
    gr.opacity_logits[i] = dlogit[l];
    gr.means[3 * i] = gmx[l], gr.means[3 * i + 1] = gmy[l], gr.means[3 * i + 2] = gmz[l];
    for (int c = 0; c < 3; ++c) gr.log_scales[3 * i + c] = dls[c][l];
    gr.quats[4 * i] = dqw[l], gr.quats[4 * i + 1] = dqx[l], gr.quats[4 * i + 2] = dqy[l],
                 gr.quats[4 * i + 3] = dqz[l];
  }
}

// Gaussians [b, e) in blocks of CW.
template <int CW>
[[gnu::always_inline]] inline void project_range(const Gaussians& g, const PoseInputs& in,
                                                 const CameraT<float>& cam, const RasterSettings& s,
                                                 size_t b, size_t e, RasterResultT<float>& out) {
  // The blocks' coefficients fetched kAhead blocks ahead (through the chunk's end too: the next
  // chunk of the same thread usually follows it).
  constexpr size_t kAhead = 4;
  for (size_t i0 = b; i0 < e; i0 += CW) {
    prefetch_sh(g, i0 + kAhead * CW, CW);
    prefetch_records(out, i0 + kAhead * CW, CW);
    project_block<CW>(g, in, cam, s, i0, int(std::min<size_t>(CW, e - i0)), out);
  }
}

void project_range_sse2(const Gaussians& g, const PoseInputs& in, const CameraT<float>& cam,
                        const RasterSettings& s, size_t b, size_t e, RasterResultT<float>& out) {
  project_range<4>(g, in, cam, s, b, e, out);
}

// (The OpenMP loop stays outside: its outlined body would not inherit the target.)
__attribute__((target("avx2"), flatten)) void project_range_avx2(
    const Gaussians& g, const PoseInputs& in, const CameraT<float>& cam, const RasterSettings& s,
    size_t b, size_t e, RasterResultT<float>& out) {
  project_range<8>(g, in, cam, s, b, e, out);
}

// Gaussians [b, e): those that were culled or took no pixel (every screen-space gradient zero
// in every thread's buffer; about 40 % of the visible ones on the bench scene, scattered among
// the others) get zero gradients without the chain rule, whose every term would be zero; the
// rest go through it in blocks of CW, listed by id. Which is which is found first for up to
// kMax Gaussians at a time, so that only those that go through the chain rule have their
// coefficients and record fetched ahead (the pass is bound by memory; in-process A/B x0.98
// against fetching every Gaussian's).
template <int CW>
[[gnu::always_inline]] inline void backward_range(const Gaussians& g, const CameraT<float>& cam,
                                                  const RasterResultT<float>& fwd, int threads,
                                                  size_t b, size_t e, RasterGradsT<float>& gr) {
  const size_t stride = size_t(kNG) * g.size();
  const int K = g.coeffs();
  size_t ids[CW];
  int n = 0;
  constexpr size_t kAhead = 32, kMax = 512;
  uint8_t chain[kMax];
  // The direction derivatives where the forward stored them (read instead of the coefficients).
  const float* dirs = g.sh_degree > 0 && !fwd.color_dirs.empty() ? fwd.color_dirs.data() : nullptr;
  for (size_t i0 = b; i0 < e; i0 += kMax) {
    const size_t i1 = std::min(e, i0 + kMax);
    for (size_t i = i0; i < i1; ++i) {
      // Every thread's nine values' bits but the signs (-0 counts as zero), or-ed.
      using U4 = uint32_t __attribute__((vector_size(16)));
      U4 bits4 = {};
      uint32_t bits = 0;
      for (int th = 0; th < threads; ++th) {
        const float* a = gr.scratch.data() + size_t(th) * stride + size_t(kNG) * i;
        U4 x, y;
        uint32_t u;
        std::memcpy(&x, a, 16), std::memcpy(&y, a + 4, 16), std::memcpy(&u, a + 8, 4);
        bits4 |= x | y, bits |= u;
      }
      bits4 <<= 1;
      const uint32_t any = bits4[0] | bits4[1] | bits4[2] | bits4[3] | bits << 1;
      chain[i - i0] = uint8_t((any != 0) & (fwd.radii[i] != 0));
    }
    for (size_t i = i0; i < i1; ++i) {
      // Gaussian i + kAhead's coefficients and record, if it goes through the chain rule (or
      // lies past this stretch), else i's own again (a select, not a branch).
      const size_t j = i + kAhead;
      const size_t ahead = j >= i1 || chain[j - i0] ? j : i;
      if (dirs) {
        // (48 bytes, on one or two lines.)
        const char* d = reinterpret_cast<const char*>(dirs + size_t(kColorDirs) * ahead);
        if (ahead < g.size()) __builtin_prefetch(d), __builtin_prefetch(d + 47);
      } else {
        prefetch_sh(g, ahead, 1);
      }
      if (ahead < g.size()) __builtin_prefetch(&fwd.packed[size_t(kRec) * ahead]);
      if (chain[i - i0]) {
        ids[n++] = i;
        if (n == CW) backward_block<CW>(g, cam, fwd, threads, ids, n, gr), n = 0;
        continue;
      }
      for (int q = 0; q < 3; ++q) gr.means[3 * i + q] = 0, gr.log_scales[3 * i + q] = 0;
      for (int q = 0; q < 4; ++q) gr.quats[4 * i + q] = 0;
      gr.opacity_logits[i] = 0;
      gr.means2d[2 * i] = gr.means2d[2 * i + 1] = 0;
      float* d = &gr.sh[i * K * 3];
      if ((3 * K) % 4 == 0) {
        for (int f = 0; f < 3 * K; f += 4) store_once(d + f, typename Lanes<CW>::V4{});
      } else {
        std::fill_n(d, 3 * K, 0.0f);
      }
    }
  }
  if (n) backward_block<CW>(g, cam, fwd, threads, ids, n, gr);
}

void backward_range_sse2(const Gaussians& g, const CameraT<float>& cam,
                         const RasterResultT<float>& fwd, int threads, size_t b, size_t e,
                         RasterGradsT<float>& gr) {
  backward_range<4>(g, cam, fwd, threads, b, e, gr);
}

__attribute__((target("avx2"), flatten)) void backward_range_avx2(const Gaussians& g,
                                                                  const CameraT<float>& cam,
                                                                  const RasterResultT<float>& fwd,
                                                                  int threads, size_t b, size_t e,
                                                                  RasterGradsT<float>& gr) {
  backward_range<8>(g, cam, fwd, threads, b, e, gr);
}

}  // namespace

void preprocess_forward_simd(const Gaussians& g, const CameraT<float>& cam, const RasterSettings& s,
                             Isa isa, RasterResultT<float>& out, const GaussianSource* source) {
  constexpr size_t kChunk = 512;  // Gaussians a task (a multiple of both block widths)
  const size_t N = g.size();
  const long chunks = long((N + kChunk - 1) / kChunk);
#pragma omp parallel
  {
    // A source's chunk: posed into this thread's scratch (a float of padding after the means),
    // projected while it is in the cache.
    std::vector<float> scratch(source ? 8 * kChunk + 1 : 0);
#pragma omp for schedule(static)
    for (long c = 0; c < chunks; ++c) {
      const size_t b = size_t(c) * kChunk, e = std::min(N, b + kChunk);
      PoseInputs in{g.means.data(), g.quats.data(), g.opacity_logits.data(), 0, false};
      if (source) {
        float *m = scratch.data(), *q = m + 3 * kChunk + 1, *o = q + 4 * kChunk;
        source->fill(b, e, m, q, o);
        in = PoseInputs{m, q, o, b, true};
      }
      if (isa == Isa::kBaseline)
        project_range_sse2(g, in, cam, s, b, e, out);
      else
        project_range_avx2(g, in, cam, s, b, e, out);
    }
#if defined(__SSE2__)
    _mm_sfence();  // color_dirs' non-temporal stores visible before the threads join
#endif
  }
}

void preprocess_backward_simd(const GaussiansT<float>& g, const CameraT<float>& cam,
                              const RasterResultT<float>& fwd, int threads, Isa isa,
                              RasterGradsT<float>& gr) {
  constexpr size_t kChunk = 512;
  const size_t N = g.size();
  size_param_grads(gr, N, g.coeffs());
  const long chunks = long((N + kChunk - 1) / kChunk);
#pragma omp parallel
  {
#pragma omp for schedule(static)
    for (long c = 0; c < chunks; ++c) {
      const size_t b = size_t(c) * kChunk, e = std::min(N, b + kChunk);
      if (isa == Isa::kBaseline)
        backward_range_sse2(g, cam, fwd, threads, b, e, gr);
      else
        backward_range_avx2(g, cam, fwd, threads, b, e, gr);
    }
#if defined(__SSE2__)
    _mm_sfence();  // store_once's stores visible before the threads join
#endif
  }
}

}  // namespace ks::raster
