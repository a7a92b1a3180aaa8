// AVX-512 loops of the texel-space first layer (see triplane_kernels.hpp): the AVX2 blend and
// gather on 16-wide vectors. Each channel is accumulated by the same fused multiply-adds in the
// same order as in triplane_avx2.cpp, so the two give the same bits. Compiled into the portable
// build with per-function target attributes and chosen at run time (the MLP kernels' choice,
// mlp_kernels::use_avx512()).
#include <algorithm>
#include <cstdlib>

#include "reconstruct/triplane_kernels.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#define KS_TRIPLANE512_X86 1
#endif

namespace ks::triplane_kernels {

#if defined(KS_TRIPLANE512_X86)

#pragma GCC diagnostic push
// GCC 12 reports its own AVX-512 intrinsics' undefined pass-through operands (_mm512_max_ps) as
// maybe uninitialised (a known false positive).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#define KS_AVX512 __attribute__((target("avx512f,avx2,fma")))
#define KS_AVX512_INLINE __attribute__((target("avx512f,avx2,fma"), always_inline)) inline

namespace {

// Block<nv>::run(args...) for nv in [1, 4]: a block of up to 64 channels, sixteen a vector, its
// accumulators in registers.
template <template <int> class Block, class... Args>
KS_AVX512_INLINE void by_vectors(int nv, Args... args) {
  switch (nv) {
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

// Channels [c, c + 16 NV) of point i's blend (blend_range_avx2's BlendBlock, sixteen wide).
template <int NV>
struct BlendBlock {
  KS_AVX512_INLINE static void run(const float* const* rows, const float* w, const float* bias,
                                   int c, int i, float* out0, int h0, float* out1, int h1) {
    __m512 acc[NV];
    for (int v = 0; v < NV; ++v) acc[v] = _mm512_loadu_ps(bias + c + 16 * v);
    for (int t = 0; t < 12; ++t) {
      const __m512 wt = _mm512_set1_ps(w[t]);
      const float* r = rows[t] + c;
      for (int v = 0; v < NV; ++v)
        acc[v] = _mm512_fmadd_ps(wt, _mm512_loadu_ps(r + 16 * v), acc[v]);
    }
    for (int v = 0; v < NV; ++v) {
      const int ch = c + 16 * v;
      float* o =
          ch < h0 ? out0 + size_t(i) * size_t(h0) + ch : out1 + size_t(i) * size_t(h1) + (ch - h0);
      _mm512_storeu_ps(o, _mm512_max_ps(acc[v], _mm512_setzero_ps()));
    }
  }
};

// Rows [r0, r1), channels [c, c + 16 NV) (gather_rows_avx2's GatherBlock, sixteen wide).
template <int NV>
struct GatherBlock {
  KS_AVX512_INLINE static void run(const int* start, const int* point, const float* weight, int r0,
                                   int r1, const float* d, int H, float* out, int c) {
    constexpr int K = 16;  // fetch an entry's row this many entries ahead
    const int e_end = start[r1];
    for (int r = r0; r < r1; ++r) {
      __m512 acc[NV];
      for (int v = 0; v < NV; ++v) acc[v] = _mm512_setzero_ps();
      for (int e = start[r]; e < start[r + 1]; ++e) {
        if (e + K < e_end) {
          const char* a = reinterpret_cast<const char*>(d + size_t(point[e + K]) * size_t(H) + c);
          for (int off = 0; off < 64 * NV; off += 64) _mm_prefetch(a + off, _MM_HINT_T0);
        }
        const __m512 w = _mm512_set1_ps(weight[e]);
        const float* g = d + size_t(point[e]) * size_t(H) + c;
        for (int v = 0; v < NV; ++v)
          acc[v] = _mm512_fmadd_ps(w, _mm512_loadu_ps(g + 16 * v), acc[v]);
      }
      float* o = out + size_t(r - r0) * size_t(H) + c;
      for (int v = 0; v < NV; ++v) _mm512_storeu_ps(o + 16 * v, acc[v]);
    }
  }
};

}  // namespace

void KS_AVX512 blend_range_avx512(const Taps* taps, int n, const float* Q, int H, const float* bias,
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
      by_vectors<BlendBlock>(std::min(4, (H - c) / 16), rows, w, bias, c, i, out0, h0, out1, h1);
  }
}

void KS_AVX512 gather_rows_avx512(const int* start, const int* point, const float* weight, int r0,
                                  int r1, const float* d, int H, float* out) {
  for (int c = 0; c < H; c += 64)
    by_vectors<GatherBlock>(std::min(4, (H - c) / 16), start, point, weight, r0, r1, d, H, out, c);
}

#pragma GCC diagnostic pop

#else  // not x86-64: never selected (mlp_kernels::use_avx512() is false)

void blend_range_avx512(const Taps*, int, const float*, int, const float*, int, int, float*, int,
                        float*) {
  std::abort();
}
void gather_rows_avx512(const int*, const int*, const float*, int, int, const float*, int, float*) {
  std::abort();
}

#endif

}  // namespace ks::triplane_kernels
