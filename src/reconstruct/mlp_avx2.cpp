// AVX2+FMA kernels for the float decoder MLP (see mlp_kernels.hpp). Compiled into the portable
// build with per-function target attributes and chosen at run time; no Eigen in this file.
#include <cstdint>
#include <cstdlib>

#include "core/env.hpp"
#include "reconstruct/mlp_kernels.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define KS_MLP_X86 1
#endif

namespace ks::mlp_kernels {

namespace {
Path g_path = Path::kAuto;
}  // namespace

bool cpu_has_avx2_fma() {
#if defined(KS_MLP_X86)
  static const bool ok = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return ok;
#else
  return false;
#endif
}

void set_path(Path p) {
  g_path = p;
}

bool use_avx2() {
  static const bool env_off = env_flag("KS_MLP_NO_AVX2");
  switch (g_path) {
    case Path::kEigen:
      return false;
    case Path::kAvx2:
    case Path::kAvx512:
      return cpu_has_avx2_fma();
    case Path::kAuto:
      break;
  }
  return cpu_has_avx2_fma() && !env_off;
}

bool use_avx512() {
  static const bool env_off = env_flag("KS_MLP_NO_AVX512");
  switch (g_path) {
    case Path::kEigen:
    case Path::kAvx2:
      return false;
    case Path::kAvx512:
      return cpu_has_avx512();
    case Path::kAuto:
      break;
  }
  return cpu_has_avx512() && use_avx2() && !env_off;
}

#if defined(KS_MLP_X86)

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

#define KS_AVX2 __attribute__((target("avx2,fma")))
#define KS_AVX2_INLINE __attribute__((target("avx2,fma"), always_inline)) inline

namespace {

using std::ptrdiff_t;

// Lane masks for a partial vector of t valid rows (1..8): kMaskTab + 8 - t.
alignas(32) const int32_t kMaskTab[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};

KS_AVX2_INLINE __m256i tail_mask(int valid) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kMaskTab + 8 - valid));
}

// ---------------------------------------------------------------------------------------------
// Y(:, p) = epilogue(A X(:, p)): a tile of R row vectors (8R rows from r0) x P points. The R
// weight vectors of column j are loaded once and used for the P points; X(j, p) is broadcast.
template <int R, int P, Epilogue E>
KS_AVX2_INLINE void gemm_tile(const float* A, int lda, int k, int r0, int rows, const float* X,
                              ptrdiff_t ldx, float* Y, ptrdiff_t ldy, const float* bias,
                              const float* M, ptrdiff_t ldm) {
  __m256 acc[P][R];
#pragma GCC unroll 16
  for (int p = 0; p < P; ++p)
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) acc[p][r] = _mm256_setzero_ps();
  const float* a = A + r0;
  for (int j = 0; j < k; ++j, a += lda) {
    __m256 w[R];
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) w[r] = _mm256_loadu_ps(a + 8 * r);
#pragma GCC unroll 16
    for (int p = 0; p < P; ++p) {
      const __m256 x = _mm256_broadcast_ss(X + p * ldx + j);
#pragma GCC unroll 4
      for (int r = 0; r < R; ++r) acc[p][r] = _mm256_fmadd_ps(w[r], x, acc[p][r]);
    }
  }
  const __m256 zero = _mm256_setzero_ps();
#pragma GCC unroll 4
  for (int r = 0; r < R; ++r) {
    const int row = r0 + 8 * r;
    const bool full = rows - row >= 8;
    const __m256i mask = tail_mask(full ? 8 : rows - row);
    __m256 bv = zero;
    if constexpr (E == Epilogue::kBias || E == Epilogue::kBiasRelu)
      bv = _mm256_loadu_ps(bias + row);
#pragma GCC unroll 16
    for (int p = 0; p < P; ++p) {
      __m256 v = acc[p][r];
      if constexpr (E == Epilogue::kBias || E == Epilogue::kBiasRelu) v = _mm256_add_ps(v, bv);
      if constexpr (E == Epilogue::kBiasRelu) v = _mm256_max_ps(v, zero);
      if constexpr (E == Epilogue::kMask) {
        const float* m = M + p * ldm + row;
        const __m256 mv = full ? _mm256_loadu_ps(m) : _mm256_maskload_ps(m, mask);
        v = _mm256_and_ps(v, _mm256_cmp_ps(mv, zero, _CMP_GT_OQ));
      }
      float* y = Y + p * ldy + row;
      if constexpr (E == Epilogue::kAdd)
        v = _mm256_add_ps(v, full ? _mm256_loadu_ps(y) : _mm256_maskload_ps(y, mask));
      if (full)
        _mm256_storeu_ps(y, v);
      else
        _mm256_maskstore_ps(y, mask, v);
    }
  }
}

// All row chunks for P points: 16-row chunks, then an 8-row one if the padded row count is odd
// in vectors.
template <int P, Epilogue E>
KS_AVX2_INLINE void gemm_group(const float* A, int lda, int k, int rows, const float* X,
                               ptrdiff_t ldx, float* Y, ptrdiff_t ldy, const float* bias,
                               const float* M, ptrdiff_t ldm) {
  int r0 = 0;
  if constexpr (P <= 6)
    for (; r0 + 16 <= lda; r0 += 16)
      gemm_tile<2, P, E>(A, lda, k, r0, rows, X, ldx, Y, ldy, bias, M, ldm);
  for (; r0 < lda; r0 += 8) gemm_tile<1, P, E>(A, lda, k, r0, rows, X, ldx, Y, ldy, bias, M, ldm);
}

// The last rem (< PMAX) points, one group.
template <int PMAX, Epilogue E>
KS_AVX2_INLINE void gemm_rest(int rem, const float* A, int lda, int k, int rows, const float* X,
                              ptrdiff_t ldx, float* Y, ptrdiff_t ldy, const float* bias,
                              const float* M, ptrdiff_t ldm) {
  if constexpr (PMAX > 0) {
    if (rem == PMAX)
      gemm_group<PMAX, E>(A, lda, k, rows, X, ldx, Y, ldy, bias, M, ldm);
    else
      gemm_rest<PMAX - 1, E>(rem, A, lda, k, rows, X, ldx, Y, ldy, bias, M, ldm);
  }
}

// All n points in groups of G, then the remainder as one smaller group.
template <int G, Epilogue E>
KS_AVX2_INLINE void gemm_sweep(const float* A, int lda, int k, int rows, const float* X,
                               ptrdiff_t ldx, int n, float* Y, ptrdiff_t ldy, const float* bias,
                               const float* M, ptrdiff_t ldm) {
  int p = 0;
  for (; p + G <= n; p += G)
    gemm_group<G, E>(A, lda, k, rows, X + p * ldx, ldx, Y + p * ldy, ldy, bias,
                     M ? M + p * ldm : nullptr, ldm);
  if (p < n)
    gemm_rest<G - 1, E>(n - p, A, lda, k, rows, X + p * ldx, ldx, Y + p * ldy, ldy, bias,
                        M ? M + p * ldm : nullptr, ldm);
}

template <Epilogue E>
KS_AVX2 void gemm_cols_impl(const float* A, int rows, int k, const float* X, ptrdiff_t ldx, int n,
                            float* Y, ptrdiff_t ldy, const float* bias, const float* M,
                            ptrdiff_t ldm) {
  const int lda = pad8(rows);
  // One row vector: 12 points a group (12 accumulators); otherwise 16 rows x 6 points.
  if (lda == 8)
    gemm_sweep<12, E>(A, lda, k, rows, X, ldx, n, Y, ldy, bias, M, ldm);
  else
    gemm_sweep<6, E>(A, lda, k, rows, X, ldx, n, Y, ldy, bias, M, ldm);
}

// ---------------------------------------------------------------------------------------------
// G(r0.., c0..c0+J) += D X^T over n points: R row vectors x J columns held in registers; per
// point, R loads of D and J broadcasts of X. TAIL: the last row vector is partial (masked load).
template <int R, int J, bool TAIL>
KS_AVX2_INLINE void outer_tile(const float* D, ptrdiff_t ldd, int r0, int rows, const float* X,
                               ptrdiff_t ldx, int c0, int n, float* G, int ldg) {
  __m256 acc[J][R];
#pragma GCC unroll 16
  for (int j = 0; j < J; ++j)
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) acc[j][r] = _mm256_loadu_ps(G + (c0 + j) * ldg + r0 + 8 * r);
  const __m256i mask = tail_mask(TAIL ? rows - (r0 + 8 * (R - 1)) : 8);
  const float* d = D + r0;
  const float* x = X + c0;
#pragma GCC unroll 2
  for (int p = 0; p < n; ++p, d += ldd, x += ldx) {
    __m256 dv[R];
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r)
      dv[r] =
          (TAIL && r == R - 1) ? _mm256_maskload_ps(d + 8 * r, mask) : _mm256_loadu_ps(d + 8 * r);
#pragma GCC unroll 16
    for (int j = 0; j < J; ++j) {
      const __m256 xv = _mm256_broadcast_ss(x + j);
#pragma GCC unroll 4
      for (int r = 0; r < R; ++r) acc[j][r] = _mm256_fmadd_ps(dv[r], xv, acc[j][r]);
    }
  }
#pragma GCC unroll 16
  for (int j = 0; j < J; ++j)
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) _mm256_storeu_ps(G + (c0 + j) * ldg + r0 + 8 * r, acc[j][r]);
}

template <int R, int JMAX, bool TAIL>
KS_AVX2_INLINE void outer_rest(int rem, const float* D, ptrdiff_t ldd, int r0, int rows,
                               const float* X, ptrdiff_t ldx, int c0, int n, float* G, int ldg) {
  if constexpr (JMAX > 0) {
    if (rem == JMAX)
      outer_tile<R, JMAX, TAIL>(D, ldd, r0, rows, X, ldx, c0, n, G, ldg);
    else
      outer_rest<R, JMAX - 1, TAIL>(rem, D, ldd, r0, rows, X, ldx, c0, n, G, ldg);
  }
}

// All columns for one row chunk: 2 vectors x 6 columns, or 1 vector x 12 columns.
template <int R, bool TAIL>
KS_AVX2_INLINE void outer_chunk(const float* D, ptrdiff_t ldd, int r0, int rows, const float* X,
                                ptrdiff_t ldx, int k, int n, float* G, int ldg) {
  constexpr int J = R == 2 ? 6 : 12;
  int c0 = 0;
  for (; c0 + J <= k; c0 += J) outer_tile<R, J, TAIL>(D, ldd, r0, rows, X, ldx, c0, n, G, ldg);
  if (c0 < k) outer_rest<R, J - 1, TAIL>(k - c0, D, ldd, r0, rows, X, ldx, c0, n, G, ldg);
}

// gb += rowsum(D), points in order.
KS_AVX2 void rowsum_acc_impl(const float* D, ptrdiff_t ldd, int rows, int n, float* gb) {
  const int ldg = pad8(rows);
  for (int r0 = 0; r0 < ldg; r0 += 8) {
    const bool full = rows - r0 >= 8;
    const __m256i mask = tail_mask(full ? 8 : rows - r0);
    __m256 s = _mm256_loadu_ps(gb + r0);
    const float* d = D + r0;
    if (full)
      for (int p = 0; p < n; ++p, d += ldd) s = _mm256_add_ps(s, _mm256_loadu_ps(d));
    else
      for (int p = 0; p < n; ++p, d += ldd) s = _mm256_add_ps(s, _mm256_maskload_ps(d, mask));
    _mm256_storeu_ps(gb + r0, s);
  }
}

KS_AVX2 void outer_acc_impl(const float* D, ptrdiff_t ldd, int rows, const float* X, ptrdiff_t ldx,
                            int k, int n, float* G, float* gb) {
  const int ldg = pad8(rows);
  int r0 = 0;
  if (ldg > 8)
    for (; r0 + 16 <= ldg; r0 += 16) {
      if (r0 + 16 > rows)
        outer_chunk<2, true>(D, ldd, r0, rows, X, ldx, k, n, G, ldg);
      else
        outer_chunk<2, false>(D, ldd, r0, rows, X, ldx, k, n, G, ldg);
    }
  for (; r0 < ldg; r0 += 8) {
    if (r0 + 8 > rows)
      outer_chunk<1, true>(D, ldd, r0, rows, X, ldx, k, n, G, ldg);
    else
      outer_chunk<1, false>(D, ldd, r0, rows, X, ldx, k, n, G, ldg);
  }
  if (gb) rowsum_acc_impl(D, ldd, rows, n, gb);
}

}  // namespace

void gemm_cols_avx2(const float* A, int rows, int k, const float* X, std::ptrdiff_t ldx, int n,
                    float* Y, std::ptrdiff_t ldy, Epilogue epi, const float* bias, const float* M,
                    std::ptrdiff_t ldm) {
  with_epilogue(epi, [&](auto e) {
    gemm_cols_impl<decltype(e)::value>(A, rows, k, X, ldx, n, Y, ldy, bias, M, ldm);
  });
}

void outer_acc_avx2(const float* D, std::ptrdiff_t ldd, int rows, const float* X,
                    std::ptrdiff_t ldx, int k, int n, float* G, float* gb) {
  outer_acc_impl(D, ldd, rows, X, ldx, k, n, G, gb);
}

void rowsum_acc_avx2(const float* D, std::ptrdiff_t ldd, int rows, int n, float* gb) {
  rowsum_acc_impl(D, ldd, rows, n, gb);
}

#pragma GCC diagnostic pop

#else  // not x86: never selected (use_avx2() is false)

void gemm_cols_avx2(const float*, int, int, const float*, std::ptrdiff_t, int, float*,
                    std::ptrdiff_t, Epilogue, const float*, const float*, std::ptrdiff_t) {
  std::abort();
}
void outer_acc_avx2(const float*, std::ptrdiff_t, int, const float*, std::ptrdiff_t, int, int,
                    float*, float*) {
  std::abort();
}
void rowsum_acc_avx2(const float*, std::ptrdiff_t, int, int, float*) {
  std::abort();
}

#endif

}  // namespace ks::mlp_kernels
