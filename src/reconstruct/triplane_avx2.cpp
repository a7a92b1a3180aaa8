// AVX2+FMA loops of the float triplane (see triplane_kernels.hpp): a lookup's four texels are
// blended, or its gradient scattered to them, eight channels a vector. Compiled into the portable
// build with per-function target attributes and chosen at run time.
#include <algorithm>
#include <cstdlib>

#include "core/env.hpp"
#include "reconstruct/mlp_kernels.hpp"
#include "reconstruct/triplane_kernels.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define KS_TRIPLANE_X86 1
#endif

namespace ks::triplane_kernels {

namespace {
Path g_path = Path::kAuto;
}  // namespace

void set_path(Path p) {
  g_path = p;
}

bool use_avx2(int channels) {
  static const bool env_off = env_flag("KS_TRIPLANE_NO_AVX2");
  if (channels % 8 != 0 || g_path == Path::kPortable || !mlp_kernels::cpu_has_avx2_fma())
    return false;
  return g_path == Path::kAvx2 || !env_off;
}

#if defined(KS_TRIPLANE_X86)

#define KS_AVX2 __attribute__((target("avx2,fma")))

void KS_AVX2 forward_range_avx2(const TriplaneT<float>& tp, const float* xs, const float* ys,
                                const float* zs, int i0, int i1, float* feats) {
  const int C = tp.channels;
  const size_t F = 3 * size_t(C);
  for (int i = i0; i < i1; ++i) {
    float* out = feats + size_t(i) * F;
    for (int p = 0; p < 3; ++p) {
      const Bilinear<float> b = lookup(tp, p, xs[i], ys[i], zs[i]);
      const auto [t00, t10, t01, t11] = texels(tp.planes.data() + p * tp.plane_size(), b, C);
      const __m256 w00 = _mm256_set1_ps(b.w00), w10 = _mm256_set1_ps(b.w10);
      const __m256 w01 = _mm256_set1_ps(b.w01), w11 = _mm256_set1_ps(b.w11);
      float* o = out + p * C;
      for (int c = 0; c < C; c += 8) {
        __m256 acc = _mm256_mul_ps(w00, _mm256_loadu_ps(t00 + c));
        acc = _mm256_fmadd_ps(w10, _mm256_loadu_ps(t10 + c), acc);
        acc = _mm256_fmadd_ps(w01, _mm256_loadu_ps(t01 + c), acc);
        acc = _mm256_fmadd_ps(w11, _mm256_loadu_ps(t11 + c), acc);
        _mm256_storeu_ps(o + c, acc);
      }
    }
  }
}

void KS_AVX2 backward_run_avx2(const TriplaneT<float>& tp, int p, const float* xs, const float* ys,
                               const float* zs, const int* ord, int k0, int k1, const float* dfeats,
                               float* dplane, int ahead) {
  const int C = tp.channels;
  const size_t F = 3 * size_t(C);
  for (int k = k0; k < k1; ++k) {
    const int i = ord[k];
    // The point gradients are read out of order: fetch a later point's ahead of its turn.
    if (k + ahead < k1) {
      const char* a = reinterpret_cast<const char*>(dfeats + size_t(ord[k + ahead]) * F + p * C);
      for (int off = 0; off < int(sizeof(float)) * C; off += 64) _mm_prefetch(a + off, _MM_HINT_T0);
    }
    const Bilinear<float> b = lookup(tp, p, xs[i], ys[i], zs[i]);
    const float* g = dfeats + size_t(i) * F + p * C;
    const auto [t00, t10, t01, t11] = texels(dplane, b, C);
    const __m256 w00 = _mm256_set1_ps(b.w00), w10 = _mm256_set1_ps(b.w10);
    const __m256 w01 = _mm256_set1_ps(b.w01), w11 = _mm256_set1_ps(b.w11);
    for (int c = 0; c < C; c += 8) {
      const __m256 gc = _mm256_loadu_ps(g + c);
      _mm256_storeu_ps(t00 + c, _mm256_fmadd_ps(w00, gc, _mm256_loadu_ps(t00 + c)));
      _mm256_storeu_ps(t10 + c, _mm256_fmadd_ps(w10, gc, _mm256_loadu_ps(t10 + c)));
      _mm256_storeu_ps(t01 + c, _mm256_fmadd_ps(w01, gc, _mm256_loadu_ps(t01 + c)));
      _mm256_storeu_ps(t11 + c, _mm256_fmadd_ps(w11, gc, _mm256_loadu_ps(t11 + c)));
    }
  }
}

namespace {
// Block<nv>::run(args...) for nv in [1, 8]: a block of up to 64 channels, eight a vector, its
// accumulators in registers.
template <template <int> class Block, class... Args>
__attribute__((target("avx2,fma"), always_inline)) inline void by_vectors(int nv, Args... args) {
  switch (nv) {
    case 8:
      Block<8>::run(args...);
      break;
    case 7:
      Block<7>::run(args...);
      break;
    case 6:
      Block<6>::run(args...);
      break;
    case 5:
      Block<5>::run(args...);
      break;
    case 4:
      Block<4>::run(args...);
      break;
    case 3:
      Block<3>::run(args...);
      break;
    case 2:
      Block<2>::run(args...);
      break;
    default:
      Block<1>::run(args...);
      break;
  }
}

// Channels [c, c + 8 NV) of point i's blend: NV independent accumulators, the twelve texels in
// turn (so the fused multiply-adds of one texel do not wait on each other).
template <int NV>
struct BlendBlock {
  __attribute__((target("avx2,fma"), always_inline)) static inline void run(
      const float* const* rows, const float* w, const float* bias, int c, int i, float* out0,
      int h0, float* out1, int h1) {
    __m256 acc[NV];
    for (int v = 0; v < NV; ++v) acc[v] = _mm256_loadu_ps(bias + c + 8 * v);
    for (int t = 0; t < 12; ++t) {
      const __m256 wt = _mm256_set1_ps(w[t]);
      const float* r = rows[t] + c;
      for (int v = 0; v < NV; ++v) acc[v] = _mm256_fmadd_ps(wt, _mm256_loadu_ps(r + 8 * v), acc[v]);
    }
    for (int v = 0; v < NV; ++v) {
      const int ch = c + 8 * v;
      float* o =
          ch < h0 ? out0 + size_t(i) * size_t(h0) + ch : out1 + size_t(i) * size_t(h1) + (ch - h0);
      _mm256_storeu_ps(o, _mm256_max_ps(acc[v], _mm256_setzero_ps()));
    }
  }
};
}  // namespace

void KS_AVX2 blend_range_avx2(const Taps* taps, int n, const float* Q, int H, const float* bias,
                              int i0, int i1, float* out0, int h0, float* out1) {
  const int h1 = H - h0;
  for (int i = i0; i < i1; ++i) {
    const float* rows[12];
    float w[12];
    for (int p = 0; p < 3; ++p) {
      const Taps& tp = taps[size_t(p) * size_t(n) + size_t(i)];
      for (int t = 0; t < 4; ++t)
        rows[4 * p + t] = Q + size_t(tp.row[t]) * size_t(H), w[4 * p + t] = tp.w[t];
    }
    for (int c = 0; c < H; c += 64)
      by_vectors<BlendBlock>(std::min(8, (H - c) / 8), rows, w, bias, c, i, out0, h0, out1, h1);
  }
}

namespace {
// Rows [r0, r1), channels [c, c + 8 NV): NV independent accumulators over a row's points.
template <int NV>
struct GatherBlock {
  __attribute__((target("avx2,fma"), always_inline)) static inline void run(
      const int* start, const int* point, const float* weight, int r0, int r1, const float* d,
      int H, float* out, int c) {
    // The points' gradients are read out of order: fetch an entry's row 16 entries ahead (2.3 ms
    // off a 120-step fit's step on seed 1, 3 runs each; the same for the blend's rows of Q: no
    // gain).
    constexpr int K = 16;
    const int e_end = start[r1];
    for (int r = r0; r < r1; ++r) {
      __m256 acc[NV];
      for (int v = 0; v < NV; ++v) acc[v] = _mm256_setzero_ps();
      for (int e = start[r]; e < start[r + 1]; ++e) {
        if (e + K < e_end) {
          const char* a = reinterpret_cast<const char*>(d + size_t(point[e + K]) * size_t(H) + c);
          for (int off = 0; off < 32 * NV; off += 64) _mm_prefetch(a + off, _MM_HINT_T0);
        }
        const __m256 w = _mm256_set1_ps(weight[e]);
        const float* g = d + size_t(point[e]) * size_t(H) + c;
        for (int v = 0; v < NV; ++v)
          acc[v] = _mm256_fmadd_ps(w, _mm256_loadu_ps(g + 8 * v), acc[v]);
      }
      float* o = out + size_t(r - r0) * size_t(H) + c;
      for (int v = 0; v < NV; ++v) _mm256_storeu_ps(o + 8 * v, acc[v]);
    }
  }
};
}  // namespace

void KS_AVX2 gather_rows_avx2(const int* start, const int* point, const float* weight, int r0,
                              int r1, const float* d, int H, float* out) {
  for (int c = 0; c < H; c += 64)
    by_vectors<GatherBlock>(std::min(8, (H - c) / 8), start, point, weight, r0, r1, d, H, out, c);
}

#else  // not x86: never selected (use_avx2() is false)

void forward_range_avx2(const TriplaneT<float>&, const float*, const float*, const float*, int, int,
                        float*) {
  std::abort();
}
void backward_run_avx2(const TriplaneT<float>&, int, const float*, const float*, const float*,
                       const int*, int, int, const float*, float*, int) {
  std::abort();
}
void blend_range_avx2(const Taps*, int, const float*, int, const float*, int, int, float*, int,
                      float*) {
  std::abort();
}
void gather_rows_avx2(const int*, const int*, const float*, int, int, const float*, int, float*) {
  std::abort();
}

#endif

}  // namespace ks::triplane_kernels
