#pragma once
// The rasterizer core, templated on the scalar type (float for production, double for the
// finite-difference tests) and on the buffer structs (which share member names).
// Included only by rasterizer.cpp and raster_double.cpp.
#include <omp.h>
#include <time.h>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <type_traits>

#include "core/camera.hpp"
#include "core/error.hpp"
#include "raster/rasterizer.hpp"
#include "raster/sh.hpp"

// Vector-extension types wider than the baseline ISA (the double test path) change the ABI of
// internal helpers only; nothing here is exported.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

namespace ks::raster_detail {

// Phase timing on stderr when KS_RASTER_PROFILE is set (diagnostics only).
struct PhaseTimer {
  bool on = std::getenv("KS_RASTER_PROFILE") != nullptr;
  std::chrono::steady_clock::time_point t = std::chrono::steady_clock::now();
  double cpu = cpu_now();
  static double cpu_now() {
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  }
  void mark(const char* name) {
    if (!on) return;
    const auto now = std::chrono::steady_clock::now();
    const double c = cpu_now();
    std::fprintf(stderr, "  %s %.2f ms (master thread CPU %.2f ms)\n", name,
                 std::chrono::duration<double, std::milli>(now - t).count(), c - cpu);
    t = now;
    cpu = c;
  }
};

constexpr int kTS = kTileSize;
constexpr int kRec = 16;  // packed render record per visible Gaussian
constexpr int kNG = 9;    // per-Gaussian screen-space grads: mx, my, a, b, c, opacity, r, g, b
constexpr int kTilePixels = kTS * kTS;
constexpr int kBatch = 64;
// Pixels of a tile row processed together (one SIMD vector on the baseline SSE2 build).
#if defined(__AVX2__)
constexpr int kCW = 8;
#else
constexpr int kCW = 4;
#endif
constexpr int kCPR = kTS / kCW;      // chunks per tile row
constexpr int kChunks = kTS * kCPR;  // chunks per tile

// exp for x <= 0 that vectorises (no libm call): Cody-Waite reduction + degree-6 polynomial,
// relative error ~2e-7. The double path uses std::exp.
inline float fexp(float x) {
  x = std::max(x, -87.0f);
  const float t = x * 1.4426950408889634f;
  const float k = (t + 12582912.0f) - 12582912.0f;  // round to nearest
  const float r = (x - k * 0.693145751953125f) - k * 1.428606765330187e-06f;
  float p = 1.0f / 720.0f;
  p = p * r + 1.0f / 120.0f;
  p = p * r + 1.0f / 24.0f;
  p = p * r + 1.0f / 6.0f;
  p = p * r + 0.5f;
  p = p * r + 1.0f;
  p = p * r + 1.0f;
  const int32_t bits = (int32_t(k) + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}
inline double fexp(double x) {
  return std::exp(x);
}

// Explicit SIMD over the kCW pixels of a chunk (GCC/Clang vector extensions: SSE2 on the
// baseline build, wider with -march). The double instantiation (tests) uses std::exp per lane.
// (vector_size must not depend on a template parameter: one explicit specialisation a width.)
template <class T, int CW>
struct VecTypes;
template <>
struct VecTypes<float, 4> {
  typedef float V __attribute__((vector_size(16)));
  typedef int32_t I __attribute__((vector_size(16)));
};
template <>
struct VecTypes<float, 8> {
  typedef float V __attribute__((vector_size(32)));
  typedef int32_t I __attribute__((vector_size(32)));
};
template <>
struct VecTypes<double, 4> {
  typedef double V __attribute__((vector_size(32)));
  typedef int64_t I __attribute__((vector_size(32)));
};
template <>
struct VecTypes<double, 8> {
  typedef double V __attribute__((vector_size(64)));
  typedef int64_t I __attribute__((vector_size(64)));
};
template <class T, int CW>
struct Simd;
template <int CW>
struct Simd<float, CW> {
  typedef typename VecTypes<float, CW>::V V;
  typedef typename VecTypes<float, CW>::I I;
  typedef int32_t S;
  [[gnu::always_inline]] static V exp(V x) {
    const V lo = V{} - 87.0f;
    x = x < lo ? lo : x;
    const V t = x * 1.4426950408889634f;
    const V k = (t + 12582912.0f) - 12582912.0f;
    const V r = (x - k * 0.693145751953125f) - k * 1.428606765330187e-06f;
    V p = V{} + 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    const I bits = (__builtin_convertvector(k, I) + 127) << 23;
    return p * (V)bits;
  }
  // Number of set lanes of a comparison mask.
  [[gnu::always_inline]] static int count(const I& m) {
#if defined(__SSE2__)
    if constexpr (CW == 4) return __builtin_popcount(_mm_movemask_ps(_mm_castsi128_ps((__m128i)m)));
#endif
    int n = 0;
    for (int l = 0; l < CW; ++l) n -= int(m[l]);
    return n;
  }
};
template <int CW>
struct Simd<double, CW> {
  typedef typename VecTypes<double, CW>::V V;
  typedef typename VecTypes<double, CW>::I I;
  typedef int64_t S;
  static V exp(V x) {
    for (int l = 0; l < CW; ++l) x[l] = std::exp(x[l]);
    return x;
  }
  static int count(const I& m) {
    int n = 0;
    for (int l = 0; l < CW; ++l) n -= int(m[l]);
    return n;
  }
};

template <class V, class T>
[[gnu::always_inline]] inline V vload(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V, class T>
[[gnu::always_inline]] inline void vstore(T* p, const V& v) {
  std::memcpy(p, &v, sizeof v);
}
template <class V, int CW>
[[gnu::always_inline]] inline V lanes() {
  V v{};
  for (int l = 0; l < CW; ++l) v[l] = l;
  return v;
}

// AVX2 kernels (8 pixels a chunk) are compiled alongside the baseline ones and chosen at run
// time; the results are identical (same per-pixel arithmetic, no FMA contraction).
inline bool use_avx2() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool ok =
      __builtin_cpu_supports("avx2") && std::getenv("KS_RASTER_NO_AVX2") == nullptr;
  return ok;
#else
  return false;
#endif
}

template <class T>
inline uint32_t depth_key(T z) {
  const float f = float(z);
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;  // z > 0: the float bits are monotone in z
}

// Stable LSD radix sort of (key, id) pairs by key, 8 bits a pass, skipping constant bytes.
inline void radix_sort(std::vector<uint32_t>& keys, std::vector<uint32_t>& ids,
                       std::vector<uint32_t>& keys2, std::vector<uint32_t>& ids2) {
  const size_t n = keys.size();
  keys2.resize(n);
  ids2.resize(n);
  for (int shift = 0; shift < 32; shift += 8) {
    uint32_t hist[256] = {0};
    for (size_t i = 0; i < n; ++i) ++hist[(keys[i] >> shift) & 255u];
    bool trivial = false;
    for (int b = 0; b < 256; ++b)
      if (hist[b] == n) trivial = true;
    if (trivial) continue;
    uint32_t sum = 0;
    for (int b = 0; b < 256; ++b) {
      const uint32_t c = hist[b];
      hist[b] = sum;
      sum += c;
    }
    for (size_t i = 0; i < n; ++i) {
      const uint32_t d = hist[(keys[i] >> shift) & 255u]++;
      keys2[d] = keys[i];
      ids2[d] = ids[i];
    }
    keys.swap(keys2);
    ids.swap(ids2);
  }
}

template <class T>
struct CamT {
  Eigen::Matrix<T, 3, 3> R;
  Eigen::Matrix<T, 3, 1> t, centre;
  T fx, fy, cx, cy;
  T lox, hix, loy, hiy;  // clamp range of x/z, y/z for the Jacobian
  int W, H;
  explicit CamT(const Camera& c) {
    R = c.R.cast<T>();
    t = c.t.cast<T>();
    centre = c.centre().cast<T>();
    fx = T(c.fx), fy = T(c.fy), cx = T(c.cx), cy = T(c.cy);
    W = c.width, H = c.height;
    // 3DGS clamps x/z to +-1.3 tan(fov_x / 2), i.e. 15% of the image width beyond each edge
    // for a centred principal point. With an arbitrary (cx, cy) we clamp to the same margin
    // beyond the actual image edges: u in [-0.15 W, 1.15 W], v in [-0.15 H, 1.15 H].
    lox = (T(-0.15) * T(W) - cx) / fx;
    hix = (T(1.15) * T(W) - cx) / fx;
    loy = (T(-0.15) * T(H) - cy) / fy;
    hiy = (T(1.15) * T(H) - cy) / fy;
  }
};

template <class T>
inline Eigen::Matrix<T, 3, 3> quat_to_rot(T w, T x, T y, T z) {
  Eigen::Matrix<T, 3, 3> R;
  R << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),  //
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),   //
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return R;
}

template <class G>
void check_gaussians(const G& g) {
  const size_t n = g.size();
  const size_t K = size_t(g.coeffs());
  if (g.sh_degree < 0 || g.sh_degree > 3)
    throw Error("rasterizer: SH degree " + std::to_string(g.sh_degree) + " not in 0..3");
  if (g.means.size() != 3 * n || g.log_scales.size() != 3 * n || g.quats.size() != 4 * n ||
      g.sh.size() != n * K * 3)
    throw Error("rasterizer: inconsistent Gaussian array sizes");
}

template <class Img>
void shape_image(Img& img, int w, int h, int c) {
  img.width = w;
  img.height = h;
  img.channels = c;
  img.data.resize(size_t(w) * h * c);
}

// One tile of the forward pass; CW pixels per SIMD chunk.
template <int CW, class T, class Res>
[[gnu::always_inline]] inline void composite_tile(Res& out, int tile, int tiles_x, int W, int H,
                                                  const T* bg) {
  constexpr int kCPR_ = kTS / CW, kChunks_ = kTS * kCPR_;
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  alignas(64) T Tt[kTilePixels], C0[kTilePixels], C1[kTilePixels], C2[kTilePixels], Dp[kTilePixels];
  using SV = Simd<T, CW>;
  using V = typename SV::V;
  using VI = typename SV::I;
  using SI = typename SV::S;
  // A pixel is finished (transmittance would fall below 1e-4, or outside the image) when its
  // Tt is negative; |Tt| is its transmittance.
  alignas(64) SI last[kTilePixels];
  int chunk_live[kChunks_];  // live pixels per chunk of CW pixels of a row
  int tile_live = 0;
  for (int q = 0; q < kChunks_; ++q) chunk_live[q] = 0;
  for (int r = 0; r < kTS; ++r)
    for (int c = 0; c < kTS; ++c) {
      const int p = r * kTS + c;
      const bool in = ox + c < W && oy + r < H;
      Tt[p] = in ? T(1) : T(-1), C0[p] = C1[p] = C2[p] = Dp[p] = 0, last[p] = 0;
      chunk_live[p / CW] += in;
      tile_live += in;
    }
  const uint32_t start = out.tile_ranges[2 * tile], end = out.tile_ranges[2 * tile + 1];
  alignas(64) T bmx[kBatch], bmy[kBatch], ba[kBatch], bb[kBatch], bc[kBatch], bo[kBatch],
      br[kBatch], bgc[kBatch], bbl[kBatch], bz[kBatch];
  int by0[kBatch], by1[kBatch], bx0[kBatch], bx1[kBatch];
  for (uint32_t b0 = start; b0 < end && tile_live > 0; b0 += kBatch) {
    const int n = int(std::min<uint32_t>(kBatch, end - b0));
    for (int k = 0; k < n; ++k) {
      const T* rec = &out.packed[size_t(kRec) * out.point_list[b0 + k]];
      bmx[k] = rec[0] - T(ox);
      bmy[k] = rec[1] - T(oy);
      ba[k] = rec[2], bb[k] = rec[3], bc[k] = rec[4], bo[k] = rec[5];
      br[k] = rec[6], bgc[k] = rec[7], bbl[k] = rec[8], bz[k] = rec[9];
      bx0[k] = std::max(int(rec[10]) - ox, 0) / CW;
      bx1[k] = std::min(int(rec[11]) - ox, kTS - 1) / CW;
      by0[k] = std::max(int(rec[12]) - oy, 0);
      by1[k] = std::min(int(rec[13]) - oy, kTS - 1);
    }
    for (int k = 0; k < n && tile_live > 0; ++k) {
      const T mx = bmx[k], a = ba[k], b = bb[k], c = bc[k], o = bo[k];
      const T cr = br[k], cg = bgc[k], cb = bbl[k], zz = bz[k];
      const int32_t idx1 = int32_t(b0 - start) + k + 1;
      for (int r = by0[k]; r <= by1[k]; ++r) {
        const T dy = bmy[k] - (T(r) + T(0.5));
        const int q0 = bx0[k], q1 = bx1[k];
        const T cdy = T(0.5) * c * dy * dy, bdy = b * dy;
        for (int q = q0; q <= q1; ++q) {
          const int cq = r * kCPR_ + q;
          if (chunk_live[cq] == 0) continue;
          const int p0 = cq * CW;
          const V dx = (mx - T(q * CW) - T(0.5)) - lanes<V, CW>();
          const V pw = -(T(0.5) * a * dx * dx + cdy) - bdy * dx;
          const V og = o * SV::exp(pw);
          const V al = og < T(0.99) ? og : V{} + T(0.99);
          const V Tp = vload<V>(Tt + p0);
          const VI ok = (pw <= T(0)) & (al >= T(1.0f / 255.0f)) & (Tp > T(0));
          const V Tn = Tp * (T(1) - al);
          const VI term = ok & (Tn < T(1e-4));
          const VI con = ok & ~term;
          const V w = con ? al * Tp : V{};
          vstore(C0 + p0, vload<V>(C0 + p0) + w * cr);
          vstore(C1 + p0, vload<V>(C1 + p0) + w * cg);
          vstore(C2 + p0, vload<V>(C2 + p0) + w * cb);
          vstore(Dp + p0, vload<V>(Dp + p0) + w * zz);
          vstore(Tt + p0, con ? Tn : (term ? -Tp : Tp));
          vstore(last + p0, (con & SI(idx1)) | (~con & vload<VI>(last + p0)));
          const int nterm = SV::count(term);
          if (nterm) {
            chunk_live[cq] -= nterm;
            tile_live -= nterm;
          }
        }
      }
    }
  }
  for (int r = 0; r < kTS && oy + r < H; ++r)
    for (int c = 0; c < kTS && ox + c < W; ++c) {
      const int p = r * kTS + c;
      const size_t pix = size_t(oy + r) * W + ox + c;
      const T Tf = std::abs(Tt[p]);
      out.color.data[3 * pix] = C0[p] + Tf * bg[0];
      out.color.data[3 * pix + 1] = C1[p] + Tf * bg[1];
      out.color.data[3 * pix + 2] = C2[p] + Tf * bg[2];
      out.alpha.data[pix] = 1 - Tf;
      out.depth.data[pix] = Dp[p];
      out.final_T[pix] = Tf;
      out.n_contrib[pix] = uint32_t(last[p]);
    }
}

template <class Res>
__attribute__((target("avx2"), flatten)) void composite_tile_avx2(Res& out, int tile, int tiles_x,
                                                                  int W, int H, const float* bg) {
  composite_tile<8, float>(out, tile, tiles_x, W, H, bg);
}

// One tile of the backward pass (reverse order), accumulating into `acc` (9 per Gaussian).
template <int CW, class T, class Res, class Img>
[[gnu::always_inline]] inline void backward_tile(const Res& fwd, const Img& dLdc, const Img& dLda,
                                                 bool has_da, const T* bg, T* acc, int tile,
                                                 int tiles_x, int W, int H) {
  constexpr int kCPR_ = kTS / CW, kChunks_ = kTS * kCPR_;
  const uint32_t start = fwd.tile_ranges[2 * tile], end = fwd.tile_ranges[2 * tile + 1];
  if (start == end) return;
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  alignas(64) T Tt[kTilePixels], Tf[kTilePixels], R0[kTilePixels], R1[kTilePixels], R2[kTilePixels],
      D0[kTilePixels], D1[kTilePixels], D2[kTilePixels], DA[kTilePixels];
  using SV = Simd<T, CW>;
  using V = typename SV::V;
  using VI = typename SV::I;
  using SI = typename SV::S;
  alignas(64) SI last[kTilePixels];
  int chunk_max[kChunks_];  // max over the chunk's pixels of last contributor + 1
  int jmax = 0;
  for (int q = 0; q < kChunks_; ++q) chunk_max[q] = 0;
  for (int r = 0; r < kTS; ++r)
    for (int c = 0; c < kTS; ++c) {
      const int p = r * kTS + c;
      if (ox + c < W && oy + r < H) {
        const size_t pix = size_t(oy + r) * W + ox + c;
        Tt[p] = Tf[p] = fwd.final_T[pix];
        last[p] = SI(fwd.n_contrib[pix]);
        D0[p] = T(dLdc.data[3 * pix]), D1[p] = T(dLdc.data[3 * pix + 1]),
        D2[p] = T(dLdc.data[3 * pix + 2]);
        DA[p] = has_da ? T(dLda.data[pix]) : T(0);
      } else {
        Tt[p] = Tf[p] = 1, last[p] = 0, D0[p] = D1[p] = D2[p] = DA[p] = 0;
      }
      R0[p] = bg[0], R1[p] = bg[1], R2[p] = bg[2];
      chunk_max[p / CW] = std::max(chunk_max[p / CW], int(last[p]));
      jmax = std::max(jmax, int(last[p]));
    }
  alignas(64) T bmx[kBatch], bmy[kBatch], ba[kBatch], bb[kBatch], bc[kBatch], bo[kBatch],
      br[kBatch], bgc[kBatch], bbl[kBatch];
  int by0[kBatch], by1[kBatch], bx0[kBatch], bx1[kBatch];
  uint32_t bid[kBatch];
  for (int hi = jmax; hi > 0; hi -= kBatch) {
    const int lo = std::max(0, hi - kBatch);
    for (int j = lo; j < hi; ++j) {
      const int k = j - lo;
      const uint32_t rank = fwd.point_list[start + j];
      bid[k] = fwd.scratch_ids[rank];
      const T* rec = &fwd.packed[size_t(kRec) * rank];
      bmx[k] = rec[0] - T(ox);
      bmy[k] = rec[1] - T(oy);
      ba[k] = rec[2], bb[k] = rec[3], bc[k] = rec[4], bo[k] = rec[5];
      br[k] = rec[6], bgc[k] = rec[7], bbl[k] = rec[8];
      bx0[k] = std::max(int(rec[10]) - ox, 0) / CW;
      bx1[k] = std::min(int(rec[11]) - ox, kTS - 1) / CW;
      by0[k] = std::max(int(rec[12]) - oy, 0);
      by1[k] = std::min(int(rec[13]) - oy, kTS - 1);
    }
    for (int j = hi - 1; j >= lo; --j) {
      const int k = j - lo;
      const T mx = bmx[k], a = ba[k], b = bb[k], c = bc[k], o = bo[k];
      const T cr = br[k], cg = bgc[k], cb = bbl[k];
      V s_mx{}, s_my{}, s_a{}, s_b{}, s_c{}, s_o{}, s_r{}, s_g{}, s_bl{};
      for (int r = by0[k]; r <= by1[k]; ++r) {
        // Same expressions as the forward pass, so the skip decisions agree bit for bit.
        const T dy = bmy[k] - (T(r) + T(0.5));
        const int q0 = bx0[k], q1 = bx1[k];
        const T cdy = T(0.5) * c * dy * dy, bdy = b * dy;
        for (int q = q0; q <= q1; ++q) {
          const int cq = r * kCPR_ + q;
          if (chunk_max[cq] <= j) continue;
          const int p0 = cq * CW;
          const V dx = (mx - T(q * CW) - T(0.5)) - lanes<V, CW>();
          const V pw = -(T(0.5) * a * dx * dx + cdy) - bdy * dx;
          const V Gv = SV::exp(pw);
          const V og = o * Gv;
          const V al = og < T(0.99) ? og : V{} + T(0.99);
          const VI ok = (SI(j) < vload<VI>(last + p0)) & (pw <= T(0)) & (al >= T(1.0f / 255.0f));
          const V om = T(1) - al;
          const V Tc = vload<V>(Tt + p0);
          const V Tj = Tc / om;
          V r0 = vload<V>(R0 + p0), r1 = vload<V>(R1 + p0), r2 = vload<V>(R2 + p0);
          const V d0 = vload<V>(D0 + p0), d1 = vload<V>(D1 + p0), d2 = vload<V>(D2 + p0);
          const V dLdal = Tj * ((cr - r0) * d0 + (cg - r1) * d1 + (cb - r2) * d2) +
                          vload<V>(DA + p0) * vload<V>(Tf + p0) / om;
          const V w = ok ? al * Tj : V{};
          s_r += w * d0;
          s_g += w * d1;
          s_bl += w * d2;
          vstore(R0 + p0, ok ? cr * al + om * r0 : r0);
          vstore(R1 + p0, ok ? cg * al + om * r1 : r1);
          vstore(R2 + p0, ok ? cb * al + om * r2 : r2);
          vstore(Tt + p0, ok ? Tj : Tc);
          const V dLdog = (ok & (og <= T(0.99))) ? dLdal : V{};
          s_o += Gv * dLdog;
          const V dLdpw = og * dLdog;
          s_mx -= dLdpw * (a * dx + b * dy);
          s_my -= dLdpw * (c * dy + b * dx);
          s_a -= T(0.5) * dx * dx * dLdpw;
          s_c -= T(0.5) * dy * dy * dLdpw;
          s_b -= dx * dy * dLdpw;
        }
      }
      T* ga = acc + size_t(kNG) * bid[k];
      for (int l = 0; l < CW; ++l) {
        ga[0] += s_mx[l], ga[1] += s_my[l], ga[2] += s_a[l], ga[3] += s_b[l];
        ga[4] += s_c[l], ga[5] += s_o[l], ga[6] += s_r[l], ga[7] += s_g[l];
        ga[8] += s_bl[l];
      }
    }
  }
}

template <class Res, class Img>
__attribute__((target("avx2"), flatten)) void backward_tile_avx2(const Res& fwd, const Img& dLdc,
                                                                 const Img& dLda, bool has_da,
                                                                 const float* bg, float* acc,
                                                                 int tile, int tiles_x, int W,
                                                                 int H) {
  backward_tile<8, float>(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
}

// ---------------------------------------------------------------------------------------------
template <class G, class Res>
void forward_impl(const G& g, const Camera& camera, const RasterSettings& s, Res& out) {
  using T = typename std::decay_t<decltype(out.conics)>::value_type;
  using M3 = Eigen::Matrix<T, 3, 3>;
  using V3 = Eigen::Matrix<T, 3, 1>;
  check_gaussians(g);
  if (camera.width <= 0 || camera.height <= 0) throw Error("rasterizer: empty camera image");
  const CamT<T> cam(camera);
  const int W = cam.W, H = cam.H;
  const size_t N = g.size();
  const int deg = g.sh_degree;
  const int K = g.coeffs();
  const T lp = T(s.low_pass);
  const T near = T(s.near_plane);

  shape_image(out.color, W, H, 3);
  shape_image(out.alpha, W, H, 1);
  shape_image(out.depth, W, H, 1);
  out.radii.resize(N);
  out.means2d.resize(2 * N);
  out.conics.resize(3 * N);
  out.colors.resize(3 * N);
  out.depths.resize(N);
  out.cov3d.resize(6 * N);
  out.sh_clamped.resize(3 * N);
  out.opacities.resize(N);
  out.rects.resize(4 * N);
  out.final_T.resize(size_t(W) * H);
  out.n_contrib.resize(size_t(W) * H);
  const int tiles_x = (W + kTS - 1) / kTS, tiles_y = (H + kTS - 1) / kTS;
  const int ntiles = tiles_x * tiles_y;
  out.tile_ranges.resize(2 * size_t(ntiles));

  PhaseTimer timer;
  // 1. Cull + project + colour, one parallel pass.
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < N; ++i) {
    out.radii[i] = 0;
    int* rect = &out.rects[4 * i];
    rect[0] = 0, rect[1] = -1, rect[2] = 0, rect[3] = -1;
    const V3 m(T(g.means[3 * i]), T(g.means[3 * i + 1]), T(g.means[3 * i + 2]));
    const V3 p = cam.R * m + cam.t;
    const T z = p.z();
    if (!(z >= near)) continue;
    const T o = T(1) / (T(1) + std::exp(-T(g.opacity_logits[i])));
    if (!(o >= T(1.0 / 255.0))) continue;
    const T* q = nullptr;
    T qraw[4] = {T(g.quats[4 * i]), T(g.quats[4 * i + 1]), T(g.quats[4 * i + 2]),
                 T(g.quats[4 * i + 3])};
    q = qraw;
    const T qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(qn > T(1e-12))) continue;
    const M3 Rq = quat_to_rot(q[0] / qn, q[1] / qn, q[2] / qn, q[3] / qn);
    M3 Mm;
    for (int c = 0; c < 3; ++c) Mm.col(c) = Rq.col(c) * std::exp(T(g.log_scales[3 * i + c]));
    const M3 S3 = Mm * Mm.transpose();
    T* cv = &out.cov3d[6 * i];
    cv[0] = S3(0, 0), cv[1] = S3(0, 1), cv[2] = S3(0, 2), cv[3] = S3(1, 1), cv[4] = S3(1, 2),
    cv[5] = S3(2, 2);
    const T ux = std::clamp(p.x() / z, cam.lox, cam.hix);
    const T uy = std::clamp(p.y() / z, cam.loy, cam.hiy);
    Eigen::Matrix<T, 2, 3> J;
    J << cam.fx / z, 0, -cam.fx * ux / z, 0, cam.fy / z, -cam.fy * uy / z;
    const Eigen::Matrix<T, 2, 3> Tm = J * cam.R;
    const Eigen::Matrix<T, 2, 2> S2 = Tm * S3 * Tm.transpose();
    const T A = S2(0, 0) + lp, B = S2(0, 1), C = S2(1, 1) + lp;
    const T det = A * C - B * B;
    if (!(det > 0)) continue;
    const T u = cam.fx * p.x() / z + cam.cx, v = cam.fy * p.y() / z + cam.cy;
    // Pixel bounding box of the region where alpha >= 1/255 can hold:
    // o exp(-d^T Q d / 2) >= 1/255  <=>  d^T Q d <= 2 ln(255 o); half-widths sqrt(2 ln(255 o) A).
    const T L = std::max(T(0), std::log(T(255) * o));
    const T ex = std::sqrt(2 * L * A) + T(0.01), ey = std::sqrt(2 * L * C) + T(0.01);
    const T fx0 = std::ceil(u - ex - T(0.5)), fx1 = std::floor(u + ex - T(0.5));
    const T fy0 = std::ceil(v - ey - T(0.5)), fy1 = std::floor(v + ey - T(0.5));
    if (!(fx1 >= 0 && fy1 >= 0 && fx0 <= T(W - 1) && fy0 <= T(H - 1))) continue;
    if (!(fx0 <= fx1 && fy0 <= fy1)) continue;
    rect[0] = int(std::max(fx0, T(0)));
    rect[1] = int(std::min(fx1, T(W - 1)));
    rect[2] = int(std::max(fy0, T(0)));
    rect[3] = int(std::min(fy1, T(H - 1)));
    const T mid = T(0.5) * (A + C);
    const T lam1 = mid + std::sqrt(std::max(T(0.1), mid * mid - det));
    out.radii[i] = std::max(1, int(std::ceil(3 * std::sqrt(lam1))));
    out.means2d[2 * i] = u;
    out.means2d[2 * i + 1] = v;
    out.conics[3 * i] = C / det;
    out.conics[3 * i + 1] = -B / det;
    out.conics[3 * i + 2] = A / det;
    out.depths[i] = z;
    out.opacities[i] = o;
    // Colour from SH, view direction = mean - camera centre.
    T basis[16];
    V3 dir = m - cam.centre;
    const T dn = dir.norm();
    dir = dn > 0 ? V3(dir / dn) : V3(0, 0, 1);
    sh::basis<T>(deg, dir.x(), dir.y(), dir.z(), basis);
    for (int ch = 0; ch < 3; ++ch) {
      T c = T(0.5);
      for (int k = 0; k < K; ++k) c += basis[k] * T(g.sh[(i * K + k) * 3 + ch]);
      out.sh_clamped[3 * i + ch] = c < 0;
      out.colors[3 * i + ch] = std::max(c, T(0));
    }
  }

  timer.mark("project");
  // 2. Depth order of the visible Gaussians (one global radix sort).
  auto& keys = out.scratch_keys;
  auto& ids = out.scratch_ids;
  keys.clear();
  ids.clear();
  for (size_t i = 0; i < N; ++i)
    if (out.radii[i] > 0) {
      keys.push_back(depth_key(out.depths[i]));
      ids.push_back(uint32_t(i));
    }
  radix_sort(keys, ids, out.scratch_keys2, out.scratch_ids2);
  const size_t nvis = ids.size();
  // Render data packed per visible Gaussian in depth order (one 64-byte record for float), so
  // the tile loops read contiguous records instead of gathering from eight arrays.
  out.packed.resize(size_t(kRec) * nvis);
#pragma omp parallel for schedule(static)
  for (size_t k = 0; k < nvis; ++k) {
    const uint32_t id = ids[k];
    T* rec = &out.packed[size_t(kRec) * k];
    rec[0] = out.means2d[2 * id], rec[1] = out.means2d[2 * id + 1];
    rec[2] = out.conics[3 * id], rec[3] = out.conics[3 * id + 1], rec[4] = out.conics[3 * id + 2];
    rec[5] = out.opacities[id];
    rec[6] = out.colors[3 * id], rec[7] = out.colors[3 * id + 1], rec[8] = out.colors[3 * id + 2];
    rec[9] = out.depths[id];
    for (int q = 0; q < 4; ++q) rec[10 + q] = T(out.rects[4 * size_t(id) + q]);
    rec[14] = rec[15] = 0;
  }
  timer.mark("sort");

  // 3. Binning: per thread per tile counts, prefix sum, scatter in depth order (stable).
  const int maxthreads = omp_get_max_threads();
  auto& counts = out.scratch_counts;
  counts.resize(size_t(maxthreads) * ntiles);
#pragma omp parallel
  {
    const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
    const size_t b = nvis * tid / nt, e = nvis * (tid + 1) / nt;
    uint32_t* cnt = &counts[size_t(tid) * ntiles];
    std::fill(cnt, cnt + ntiles, 0u);
    for (size_t k = b; k < e; ++k) {
      const T* r = &out.packed[size_t(kRec) * k + 10];
      const int tx0 = int(r[0]) / kTS, tx1 = int(r[1]) / kTS, ty0 = int(r[2]) / kTS,
                ty1 = int(r[3]) / kTS;
      for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) ++cnt[ty * tiles_x + tx];
    }
#pragma omp barrier
#pragma omp single
    {
      uint32_t off = 0;
      for (int t = 0; t < ntiles; ++t) {
        out.tile_ranges[2 * t] = off;
        for (int th = 0; th < nt; ++th) {
          uint32_t& c = counts[size_t(th) * ntiles + t];
          const uint32_t tmp = c;
          c = off;
          off += tmp;
        }
        out.tile_ranges[2 * t + 1] = off;
      }
      out.point_list.resize(off);
    }
    for (size_t k = b; k < e; ++k) {
      const T* r = &out.packed[size_t(kRec) * k + 10];
      const int tx0 = int(r[0]) / kTS, tx1 = int(r[1]) / kTS, ty0 = int(r[2]) / kTS,
                ty1 = int(r[3]) / kTS;
      for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) out.point_list[cnt[ty * tiles_x + tx]++] = uint32_t(k);
    }
  }

  timer.mark("bin");
  // 4. Compositing, front to back, one tile per task.
  const T bg[3] = {T(s.background[0]), T(s.background[1]), T(s.background[2])};
#pragma omp parallel for schedule(dynamic, 2)
  for (int tile = 0; tile < ntiles; ++tile) {
    if constexpr (std::is_same_v<T, float>) {
      if (use_avx2()) {
        composite_tile_avx2(out, tile, tiles_x, W, H, bg);
        continue;
      }
    }
    composite_tile<kCW, T>(out, tile, tiles_x, W, H, bg);
  }
  timer.mark("composite");
}

template <class G, class Res, class Img, class Grads>
void backward_impl(const G& g, const Camera& camera, const RasterSettings& s, const Res& fwd,
                   const Img& dLdc, const Img& dLda, Grads& gr) {
  using T = typename std::decay_t<decltype(fwd.conics)>::value_type;
  using M3 = Eigen::Matrix<T, 3, 3>;
  using V3 = Eigen::Matrix<T, 3, 1>;
  using M2 = Eigen::Matrix<T, 2, 2>;
  check_gaussians(g);
  const CamT<T> cam(camera);
  const int W = cam.W, H = cam.H;
  const size_t N = g.size();
  const int deg = g.sh_degree;
  const int K = g.coeffs();
  if (fwd.radii.size() != N || fwd.color.width != W || fwd.color.height != H)
    throw Error("rasterize_backward: forward result does not match the Gaussians / camera");
  if (dLdc.width != W || dLdc.height != H || dLdc.channels != 3)
    throw Error("rasterize_backward: dL/dcolor must be W x H x 3");
  const bool has_da = !dLda.data.empty();
  if (has_da && (dLda.width != W || dLda.height != H || dLda.channels != 1))
    throw Error("rasterize_backward: dL/dalpha must be W x H x 1 or empty");
  const int tiles_x = (W + kTS - 1) / kTS, tiles_y = (H + kTS - 1) / kTS;
  const int ntiles = tiles_x * tiles_y;
  const int maxthreads = omp_get_max_threads();
  const size_t stride = size_t(kNG) * N;
  gr.scratch.resize(size_t(maxthreads) * stride);
  const T bg[3] = {T(s.background[0]), T(s.background[1]), T(s.background[2])};
  PhaseTimer timer;
#pragma omp parallel
  {
    const int tid = omp_get_thread_num();
    T* acc = gr.scratch.data() + size_t(tid) * stride;
    std::fill(acc, acc + stride, T(0));
    // Threads that do not run (nt < maxthreads) must not leave stale data: zero the rest.
#pragma omp single
    for (int th = omp_get_num_threads(); th < maxthreads; ++th)
      std::fill(gr.scratch.data() + size_t(th) * stride,
                gr.scratch.data() + size_t(th + 1) * stride, T(0));
#pragma omp for schedule(dynamic, 2)
    for (int tile = 0; tile < ntiles; ++tile) {
      if constexpr (std::is_same_v<T, float>) {
        if (use_avx2()) {
          backward_tile_avx2(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
          continue;
        }
      }
      backward_tile<kCW, T>(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
    }
  }

  timer.mark("backward tiles");
  // Per-Gaussian chain rule to the raw parameters.
  gr.means.resize(3 * N);
  gr.log_scales.resize(3 * N);
  gr.quats.resize(4 * N);
  gr.opacity_logits.resize(N);
  gr.sh.resize(N * size_t(K) * 3);
  gr.means2d.resize(2 * N);
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < N; ++i) {
    T gs[kNG] = {0};
    for (int th = 0; th < maxthreads; ++th) {
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
    const T o = fwd.opacities[i];
    gr.opacity_logits[i] = gs[5] * o * (1 - o);
    const V3 m(T(g.means[3 * i]), T(g.means[3 * i + 1]), T(g.means[3 * i + 2]));
    // Colour -> SH coefficients and view direction.
    T gcol[3];
    for (int ch = 0; ch < 3; ++ch) gcol[ch] = fwd.sh_clamped[3 * i + ch] ? T(0) : gs[6 + ch];
    V3 vdir = m - cam.centre;
    const T vn = vdir.norm();
    const V3 dir = vn > 0 ? V3(vdir / vn) : V3(0, 0, 1);
    T basis[16];
    sh::basis<T>(deg, dir.x(), dir.y(), dir.z(), basis);
    for (int k = 0; k < K; ++k)
      for (int ch = 0; ch < 3; ++ch) gr.sh[(i * K + k) * 3 + ch] = basis[k] * gcol[ch];
    V3 gmean = V3::Zero();
    if (deg > 0 && vn > 0) {
      T bx[16], by[16], bz[16];
      sh::basis_grad<T>(deg, dir.x(), dir.y(), dir.z(), bx, by, bz);
      V3 gdir = V3::Zero();
      for (int k = 1; k < K; ++k) {
        T w = 0;
        for (int ch = 0; ch < 3; ++ch) w += T(g.sh[(i * K + k) * 3 + ch]) * gcol[ch];
        gdir += w * V3(bx[k], by[k], bz[k]);
      }
      gmean += (gdir - dir * dir.dot(gdir)) / vn;
    }
    // Recompute the projection pieces.
    const V3 p = cam.R * m + cam.t;
    const T x = p.x(), y = p.y(), z = p.z();
    const T qr[4] = {T(g.quats[4 * i]), T(g.quats[4 * i + 1]), T(g.quats[4 * i + 2]),
                     T(g.quats[4 * i + 3])};
    const T qn = std::sqrt(qr[0] * qr[0] + qr[1] * qr[1] + qr[2] * qr[2] + qr[3] * qr[3]);
    const T qw = qr[0] / qn, qx = qr[1] / qn, qy = qr[2] / qn, qz = qr[3] / qn;
    const M3 Rq = quat_to_rot(qw, qx, qy, qz);
    V3 sc;
    M3 Mm;
    for (int c = 0; c < 3; ++c) {
      sc[c] = std::exp(T(g.log_scales[3 * i + c]));
      Mm.col(c) = Rq.col(c) * sc[c];
    }
    const M3 S3 = Mm * Mm.transpose();
    const T rx = x / z, ry = y / z;
    const T ux = std::clamp(rx, cam.lox, cam.hix), uy = std::clamp(ry, cam.loy, cam.hiy);
    Eigen::Matrix<T, 2, 3> J;
    J << cam.fx / z, 0, -cam.fx * ux / z, 0, cam.fy / z, -cam.fy * uy / z;
    const Eigen::Matrix<T, 2, 3> Tm = J * cam.R;
    // Conic -> 2D covariance (incl. low-pass, which is a constant).
    M2 Q;
    Q << fwd.conics[3 * i], fwd.conics[3 * i + 1], fwd.conics[3 * i + 1], fwd.conics[3 * i + 2];
    M2 GQ;
    GQ << gs[2], T(0.5) * gs[3], T(0.5) * gs[3], gs[4];
    const M2 GS2 = -Q * GQ * Q;
    const M3 GS3 = Tm.transpose() * GS2 * Tm;
    const Eigen::Matrix<T, 2, 3> GTm = 2 * GS2 * Tm * S3;
    const Eigen::Matrix<T, 2, 3> GJ = GTm * cam.R.transpose();
    V3 gp = V3::Zero();
    // means2d: u = fx x/z + cx, v = fy y/z + cy.
    gp.x() += gs[0] * cam.fx / z;
    gp.y() += gs[1] * cam.fy / z;
    gp.z() += -gs[0] * cam.fx * x / (z * z) - gs[1] * cam.fy * y / (z * z);
    // Jacobian entries: J00 = fx/z, J11 = fy/z, J02 = -fx ux/z, J12 = -fy uy/z.
    gp.z() += -GJ(0, 0) * cam.fx / (z * z) - GJ(1, 1) * cam.fy / (z * z);
    gp.z() += GJ(0, 2) * cam.fx * ux / (z * z) + GJ(1, 2) * cam.fy * uy / (z * z);
    if (rx > cam.lox && rx < cam.hix) {
      const T gux = -GJ(0, 2) * cam.fx / z;
      gp.x() += gux / z;
      gp.z() -= gux * x / (z * z);
    }
    if (ry > cam.loy && ry < cam.hiy) {
      const T guy = -GJ(1, 2) * cam.fy / z;
      gp.y() += guy / z;
      gp.z() -= guy * y / (z * z);
    }
    gmean += cam.R.transpose() * gp;
    for (int q = 0; q < 3; ++q) gr.means[3 * i + q] = gmean[q];
    // Covariance -> scale and rotation.
    const M3 GM = 2 * GS3 * Mm;
    M3 GR;
    for (int c = 0; c < 3; ++c) {
      GR.col(c) = GM.col(c) * sc[c];
      gr.log_scales[3 * i + c] = GM.col(c).dot(Rq.col(c)) * sc[c];
    }
    const T gw = 2 * (-qz * GR(0, 1) + qy * GR(0, 2) + qz * GR(1, 0) - qx * GR(1, 2) -
                      qy * GR(2, 0) + qx * GR(2, 1));
    const T gx = 2 * (qy * GR(0, 1) + qz * GR(0, 2) + qy * GR(1, 0) - 2 * qx * GR(1, 1) -
                      qw * GR(1, 2) + qz * GR(2, 0) + qw * GR(2, 1) - 2 * qx * GR(2, 2));
    const T gy = 2 * (-2 * qy * GR(0, 0) + qx * GR(0, 1) + qw * GR(0, 2) + qx * GR(1, 0) +
                      qz * GR(1, 2) - qw * GR(2, 0) + qz * GR(2, 1) - 2 * qy * GR(2, 2));
    const T gz = 2 * (-2 * qz * GR(0, 0) - qw * GR(0, 1) + qx * GR(0, 2) + qw * GR(1, 0) -
                      2 * qz * GR(1, 1) + qy * GR(1, 2) + qx * GR(2, 0) + qy * GR(2, 1));
    const T dotq = qw * gw + qx * gx + qy * gy + qz * gz;
    gr.quats[4 * i] = (gw - qw * dotq) / qn;
    gr.quats[4 * i + 1] = (gx - qx * dotq) / qn;
    gr.quats[4 * i + 2] = (gy - qy * dotq) / qn;
    gr.quats[4 * i + 3] = (gz - qz * dotq) / qn;
  }
  timer.mark("backward per-Gaussian");
}

}  // namespace ks::raster_detail

#pragma GCC diagnostic pop
