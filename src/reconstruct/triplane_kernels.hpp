#pragma once
// The triplane's per-point lookup (which texels, which bilinear weights) and its AVX2+FMA loops
// for float planes whose channel count is a multiple of 8 (internal to reconstruct/triplane.cpp,
// its tests and its benchmark). triplane_avx2.cpp compiles the loops with per-function target
// attributes; they are chosen at run time, and differ from the portable loops by float rounding
// only (fused multiply-adds).
#include <algorithm>
#include <cstddef>

#include "reconstruct/triplane.hpp"

namespace ks::triplane_kernels {

template <typename T>
struct Bilinear {
  int i00;  // index of the (u0, v0) texel (in texels, times channels later)
  int du, dv;
  T w00, w10, w01, w11;
};

template <typename T>
inline Bilinear<T> bilinear(T a, T b, T lo_a, T hi_a, T lo_b, T hi_b, int res) {
  const T sa = (a - lo_a) / (hi_a - lo_a) * T(res - 1);
  const T sb = (b - lo_b) / (hi_b - lo_b) * T(res - 1);
  const T ca = std::clamp(sa, T(0), T(res - 1));
  const T cb = std::clamp(sb, T(0), T(res - 1));
  int u0 = std::min(int(ca), res - 2);
  int v0 = std::min(int(cb), res - 2);
  const T fu = ca - T(u0), fv = cb - T(v0);
  Bilinear<T> r;
  r.i00 = v0 * res + u0;
  r.du = 1;
  r.dv = res;
  r.w00 = (1 - fu) * (1 - fv);
  r.w10 = fu * (1 - fv);
  r.w01 = (1 - fu) * fv;
  r.w11 = fu * fv;
  return r;
}

// A lookup's four texels in a plane (base: the plane's first entry; C channels a texel).
template <typename P>
struct Texels {
  P t00, t10, t01, t11;
};
template <typename P, typename T>
inline Texels<P> texels(P base, const Bilinear<T>& b, int C) {
  Texels<P> q;
  q.t00 = base + size_t(b.i00) * size_t(C);
  q.t10 = q.t00 + size_t(b.du) * size_t(C);
  q.t01 = q.t00 + size_t(b.dv) * size_t(C);
  q.t11 = q.t01 + size_t(b.du) * size_t(C);
  return q;
}

// Plane 0 = XY, 1 = XZ, 2 = YZ (triplane.hpp).
template <typename T>
inline Bilinear<T> lookup(const TriplaneT<T>& tp, int plane, T x, T y, T z) {
  switch (plane) {
    case 0:
      return bilinear(x, y, tp.lo[0], tp.hi[0], tp.lo[1], tp.hi[1], tp.res);
    case 1:
      return bilinear(x, z, tp.lo[0], tp.hi[0], tp.lo[2], tp.hi[2], tp.res);
    default:
      return bilinear(y, z, tp.lo[1], tp.hi[1], tp.lo[2], tp.hi[2], tp.res);
  }
}

// Whether triplane_forward / triplane_backward<float> take the AVX2 loops for planes of
// `channels` channels: the CPU has AVX2 and FMA, channels is a multiple of 8 and
// KS_TRIPLANE_NO_AVX2 is not set (set_path forces either path, for tests and benchmarks).
bool use_avx2(int channels);
enum class Path { kAuto, kPortable, kAvx2 };
void set_path(Path p);

// The features (n x 3C, point-major) of points [i0, i1).
void forward_range_avx2(const TriplaneT<float>& tp, const float* xs, const float* ys,
                        const float* zs, int i0, int i1, float* feats);
// Adds the gradients of plane p's points ord[k0..k1) (dfeats n x 3C, point-major) to that plane's
// gradient `dplane`, in that order; prefetches the point gradients `ahead` points early.
void backward_run_avx2(const TriplaneT<float>& tp, int p, const float* xs, const float* ys,
                       const float* zs, const int* ord, int k0, int k1, const float* dfeats,
                       float* dplane, int ahead);

// The decoders' first layer in texel space (reconstruct/texel_layer0.hpp). Q holds H values a
// texel (H a multiple of 8) for a compact set of texels. A point's taps in a plane: the rows of Q
// of its lookup's four texels (00, 10, 01, 11) and their bilinear weights, made once for points
// that stay fixed; taps[p n + i] for plane p, point i.
struct Taps {
  int row[4];
  float w[4];
};
// Points [i0, i1) of n: z = bias + the blend of Q's rows over the point's twelve taps, then
// max(z, 0), written as rows [0, h0) to out0 (leading dim h0) and rows [h0, H) to out1 (leading
// dim H - h0; unused when h0 == H). h0 is a multiple of 8.
void blend_range_avx2(const Taps* taps, int n, const float* Q, int H, const float* bias, int i0,
                      int i1, float* out0, int h0, float* out1);
// The same taps read the other way (for the backward): row r of Q is tapped by the points
// point[start[r] .. start[r + 1]) with weights weight[..], in increasing point order. Writes
// out(:, r - r0) = sum of weight * d(:, point) (H values a point, point-major) for rows [r0, r1),
// leading dim H.
void gather_rows_avx2(const int* start, const int* point, const float* weight, int r0, int r1,
                      const float* d, int H, float* out);
// The same two sixteen channels a vector (triplane_avx512.cpp), for H and h0 multiples of 16:
// the same bits.
void blend_range_avx512(const Taps* taps, int n, const float* Q, int H, const float* bias, int i0,
                        int i1, float* out0, int h0, float* out1);
void gather_rows_avx512(const int* start, const int* point, const float* weight, int r0, int r1,
                        const float* d, int H, float* out);

}  // namespace ks::triplane_kernels
