// AVX-512 kernels for the float decoder MLP (see mlp_kernels.hpp): the AVX2 kernels' arithmetic
// on 16-wide vectors. Every output element is accumulated by the same fused multiply-adds in the
// same order as in mlp_avx2.cpp, so the two give the same bits; only the tiling differs (twice
// the rows a vector, twice the points or columns a tile, partial vectors through lane masks).
// Compiled into the portable build with per-function target attributes and chosen at run time;
// no Eigen in this file.
#include <cstdint>
#include <cstdlib>

#include "reconstruct/mlp_kernels.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#define KS_MLP512_X86 1
#endif

namespace ks::mlp_kernels {

bool cpu_has_avx512() {
#if defined(KS_MLP512_X86)
  static const bool ok = __builtin_cpu_supports("avx512f") && cpu_has_avx2_fma();
  return ok;
#else
  return false;
#endif
}

#if defined(KS_MLP512_X86)

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
// GCC 12 reports its own AVX-512 intrinsics' undefined pass-through operands (_mm512_max_ps) as
// maybe uninitialised (a known false positive).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#define KS_AVX512 __attribute__((target("avx512f,avx2,fma")))
#define KS_AVX512_INLINE __attribute__((target("avx512f,avx2,fma"), always_inline)) inline

namespace {

using std::ptrdiff_t;

// The first `valid` lanes (clamped to 0..16).
KS_AVX512_INLINE __mmask16 lanes(int valid) {
  return valid >= 16 ? __mmask16(0xFFFF) : valid <= 0 ? __mmask16(0) : __mmask16((1u << valid) - 1);
}

// ---------------------------------------------------------------------------------------------
// Y(:, p) = epilogue(A X(:, p)): R row vectors (16R rows from r0) x P points. lda (a multiple
// of 8) may end inside the last vector: the weights are read through the lane mask (zeros
// beyond), and rows past `rows` are never stored.
template <int R, int P, Epilogue E>
KS_AVX512_INLINE void gemm_tile(const float* A, int lda, int k, int r0, int rows, const float* X,
                                ptrdiff_t ldx, float* Y, ptrdiff_t ldy, const float* bias,
                                const float* M, ptrdiff_t ldm) {
  __m512 acc[P][R];
#pragma GCC unroll 16
  for (int p = 0; p < P; ++p)
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) acc[p][r] = _mm512_setzero_ps();
  __mmask16 wm[R];
#pragma GCC unroll 4
  for (int r = 0; r < R; ++r) wm[r] = lanes(lda - (r0 + 16 * r));
  const float* a = A + r0;
  for (int j = 0; j < k; ++j, a += lda) {
    __m512 w[R];
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) w[r] = _mm512_maskz_loadu_ps(wm[r], a + 16 * r);
#pragma GCC unroll 16
    for (int p = 0; p < P; ++p) {
      const __m512 x = _mm512_set1_ps(X[p * ldx + j]);
#pragma GCC unroll 4
      for (int r = 0; r < R; ++r) acc[p][r] = _mm512_fmadd_ps(w[r], x, acc[p][r]);
    }
  }
  const __m512 zero = _mm512_setzero_ps();
#pragma GCC unroll 4
  for (int r = 0; r < R; ++r) {
    const int row = r0 + 16 * r;
    const __mmask16 sm = lanes(rows - row);
    __m512 bv = zero;
    if constexpr (E == Epilogue::kBias || E == Epilogue::kBiasRelu)
      bv = _mm512_maskz_loadu_ps(wm[r], bias + row);
#pragma GCC unroll 16
    for (int p = 0; p < P; ++p) {
      __m512 v = acc[p][r];
      if constexpr (E == Epilogue::kBias || E == Epilogue::kBiasRelu) v = _mm512_add_ps(v, bv);
      if constexpr (E == Epilogue::kBiasRelu) v = _mm512_max_ps(v, zero);
      if constexpr (E == Epilogue::kMask) {
        const __m512 mv = _mm512_maskz_loadu_ps(sm, M + p * ldm + row);
        v = _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(mv, zero, _CMP_GT_OQ), v);
      }
      float* y = Y + p * ldy + row;
      if constexpr (E == Epilogue::kAdd) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(sm, y));
      _mm512_mask_storeu_ps(y, sm, v);
    }
  }
}

// All row chunks for P points: 32-row chunks, then a 16-row one (possibly partial).
template <int P, Epilogue E>
KS_AVX512_INLINE void gemm_group(const float* A, int lda, int k, int rows, const float* X,
                                 ptrdiff_t ldx, float* Y, ptrdiff_t ldy, const float* bias,
                                 const float* M, ptrdiff_t ldm) {
  int r0 = 0;
  for (; r0 + 32 <= lda; r0 += 32)
    gemm_tile<2, P, E>(A, lda, k, r0, rows, X, ldx, Y, ldy, bias, M, ldm);
  for (; r0 < lda; r0 += 16) gemm_tile<1, P, E>(A, lda, k, r0, rows, X, ldx, Y, ldy, bias, M, ldm);
}

template <int PMAX, Epilogue E>
KS_AVX512_INLINE void gemm_rest(int rem, const float* A, int lda, int k, int rows, const float* X,
                                ptrdiff_t ldx, float* Y, ptrdiff_t ldy, const float* bias,
                                const float* M, ptrdiff_t ldm) {
  if constexpr (PMAX > 0) {
    if (rem == PMAX)
      gemm_group<PMAX, E>(A, lda, k, rows, X, ldx, Y, ldy, bias, M, ldm);
    else
      gemm_rest<PMAX - 1, E>(rem, A, lda, k, rows, X, ldx, Y, ldy, bias, M, ldm);
  }
}

template <Epilogue E>
KS_AVX512 void gemm_cols_impl(const float* A, int rows, int k, const float* X, ptrdiff_t ldx, int n,
                              float* Y, ptrdiff_t ldy, const float* bias, const float* M,
                              ptrdiff_t ldm) {
  // 12 points a group: 2 x 12 accumulators for a 32-row chunk, 12 for a 16-row one.
  constexpr int G = 12;
  const int lda = pad8(rows);
  int p = 0;
  for (; p + G <= n; p += G)
    gemm_group<G, E>(A, lda, k, rows, X + p * ldx, ldx, Y + p * ldy, ldy, bias,
                     M ? M + p * ldm : nullptr, ldm);
  if (p < n)
    gemm_rest<G - 1, E>(n - p, A, lda, k, rows, X + p * ldx, ldx, Y + p * ldy, ldy, bias,
                        M ? M + p * ldm : nullptr, ldm);
}

// ---------------------------------------------------------------------------------------------
// G(r0.., c0..c0+J) += D X^T over n points: R row vectors x J columns in registers; per point,
// R loads of D (through the lane mask where `rows` ends inside a vector) and J broadcasts of X.
template <int R, int J>
KS_AVX512_INLINE void outer_tile(const float* D, ptrdiff_t ldd, int r0, int rows, int ldg,
                                 const float* X, ptrdiff_t ldx, int c0, int n, float* G) {
  __mmask16 dm[R], gm[R];
#pragma GCC unroll 4
  for (int r = 0; r < R; ++r) {
    dm[r] = lanes(rows - (r0 + 16 * r));
    gm[r] = lanes(ldg - (r0 + 16 * r));
  }
  __m512 acc[J][R];
#pragma GCC unroll 16
  for (int j = 0; j < J; ++j)
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r)
      acc[j][r] = _mm512_maskz_loadu_ps(gm[r], G + (c0 + j) * ldg + r0 + 16 * r);
  const float* d = D + r0;
  const float* x = X + c0;
#pragma GCC unroll 2
  for (int p = 0; p < n; ++p, d += ldd, x += ldx) {
    __m512 dv[R];
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) dv[r] = _mm512_maskz_loadu_ps(dm[r], d + 16 * r);
#pragma GCC unroll 16
    for (int j = 0; j < J; ++j) {
      const __m512 xv = _mm512_set1_ps(x[j]);
#pragma GCC unroll 4
      for (int r = 0; r < R; ++r) acc[j][r] = _mm512_fmadd_ps(dv[r], xv, acc[j][r]);
    }
  }
#pragma GCC unroll 16
  for (int j = 0; j < J; ++j)
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r)
      _mm512_mask_storeu_ps(G + (c0 + j) * ldg + r0 + 16 * r, gm[r], acc[j][r]);
}

template <int R, int JMAX>
KS_AVX512_INLINE void outer_rest(int rem, const float* D, ptrdiff_t ldd, int r0, int rows, int ldg,
                                 const float* X, ptrdiff_t ldx, int c0, int n, float* G) {
  if constexpr (JMAX > 0) {
    if (rem == JMAX)
      outer_tile<R, JMAX>(D, ldd, r0, rows, ldg, X, ldx, c0, n, G);
    else
      outer_rest<R, JMAX - 1>(rem, D, ldd, r0, rows, ldg, X, ldx, c0, n, G);
  }
}

// All columns for one row chunk: 2 vectors x 12 columns, or 1 vector x 24 columns.
template <int R>
KS_AVX512_INLINE void outer_chunk(const float* D, ptrdiff_t ldd, int r0, int rows, int ldg,
                                  const float* X, ptrdiff_t ldx, int k, int n, float* G) {
  constexpr int J = R == 2 ? 12 : 24;
  int c0 = 0;
  for (; c0 + J <= k; c0 += J) outer_tile<R, J>(D, ldd, r0, rows, ldg, X, ldx, c0, n, G);
  if (c0 < k) outer_rest<R, J - 1>(k - c0, D, ldd, r0, rows, ldg, X, ldx, c0, n, G);
}

// gb += rowsum(D), points in order.
KS_AVX512 void rowsum_acc_impl(const float* D, ptrdiff_t ldd, int rows, int n, float* gb) {
  const int ldg = pad8(rows);
  for (int r0 = 0; r0 < ldg; r0 += 16) {
    const __mmask16 dm = lanes(rows - r0), gm = lanes(ldg - r0);
    __m512 s = _mm512_maskz_loadu_ps(gm, gb + r0);
    const float* d = D + r0;
    for (int p = 0; p < n; ++p, d += ldd) s = _mm512_add_ps(s, _mm512_maskz_loadu_ps(dm, d));
    _mm512_mask_storeu_ps(gb + r0, gm, s);
  }
}

KS_AVX512 void outer_acc_impl(const float* D, ptrdiff_t ldd, int rows, const float* X,
                              ptrdiff_t ldx, int k, int n, float* G, float* gb) {
  const int ldg = pad8(rows);
  int r0 = 0;
  for (; r0 + 32 <= ldg; r0 += 32) outer_chunk<2>(D, ldd, r0, rows, ldg, X, ldx, k, n, G);
  for (; r0 < ldg; r0 += 16) outer_chunk<1>(D, ldd, r0, rows, ldg, X, ldx, k, n, G);
  if (gb) rowsum_acc_impl(D, ldd, rows, n, gb);
}

}  // namespace

void gemm_cols_avx512(const float* A, int rows, int k, const float* X, std::ptrdiff_t ldx, int n,
                      float* Y, std::ptrdiff_t ldy, Epilogue epi, const float* bias, const float* M,
                      std::ptrdiff_t ldm) {
  with_epilogue(epi, [&](auto e) {
    gemm_cols_impl<decltype(e)::value>(A, rows, k, X, ldx, n, Y, ldy, bias, M, ldm);
  });
}

void outer_acc_avx512(const float* D, std::ptrdiff_t ldd, int rows, const float* X,
                      std::ptrdiff_t ldx, int k, int n, float* G, float* gb) {
  outer_acc_impl(D, ldd, rows, X, ldx, k, n, G, gb);
}

void rowsum_acc_avx512(const float* D, std::ptrdiff_t ldd, int rows, int n, float* gb) {
  rowsum_acc_impl(D, ldd, rows, n, gb);
}

#pragma GCC diagnostic pop

#else  // not x86-64: never selected (use_avx512() is false)

void gemm_cols_avx512(const float*, int, int, const float*, std::ptrdiff_t, int, float*,
                      std::ptrdiff_t, Epilogue, const float*, const float*, std::ptrdiff_t) {
  std::abort();
}
void outer_acc_avx512(const float*, std::ptrdiff_t, int, const float*, std::ptrdiff_t, int, int,
                      float*, float*) {
  std::abort();
}
void rowsum_acc_avx512(const float*, std::ptrdiff_t, int, int, float*) {
  std::abort();
}

#endif

}  // namespace ks::mlp_kernels
