#pragma once
// Hand-written AVX2+FMA and AVX-512 kernels for the float decoder MLP (internal to
// reconstruct/mlp.cpp, the texel layer and their tests). Plain pointers, no Eigen: mlp_avx2.cpp
// and mlp_avx512.cpp are compiled with per-function target attributes, and Eigen code
// instantiated there with a different ISA would be an ODR hazard. The AVX-512 kernels accumulate
// every element by the same operations in the same order as the AVX2 ones: the same bits.
//
// All matrices are column-major with one point per column ("point-major": a point's values are
// contiguous); ld* is the distance between two points' columns in floats. Weight operands are
// packed with their row count padded to a multiple of 8 (pad rows are zero), 32-byte aligned.
#include <cstddef>
#include <type_traits>

namespace ks::mlp_kernels {

// Rows rounded up to the AVX2 vector width.
inline int pad8(int rows) {
  return (rows + 7) & ~7;
}

enum class Epilogue {
  kNone,      // Y = A X
  kBias,      // Y = A X + b
  kBiasRelu,  // Y = max(A X + b, 0)
  kMask,      // Y = (M > 0) ? A X : 0   (ReLU backward, M = the layer's ReLU output)
  kAdd,       // Y = A X + Y   (the product finished first, then one addition per element)
};

// f(std::integral_constant<Epilogue, e>{}): a kernel's epilogue as a template argument.
template <class F>
inline void with_epilogue(Epilogue e, F&& f) {
  switch (e) {
    case Epilogue::kNone:
      return f(std::integral_constant<Epilogue, Epilogue::kNone>{});
    case Epilogue::kBias:
      return f(std::integral_constant<Epilogue, Epilogue::kBias>{});
    case Epilogue::kBiasRelu:
      return f(std::integral_constant<Epilogue, Epilogue::kBiasRelu>{});
    case Epilogue::kMask:
      return f(std::integral_constant<Epilogue, Epilogue::kMask>{});
    case Epilogue::kAdd:
      return f(std::integral_constant<Epilogue, Epilogue::kAdd>{});
  }
}

// Y(:, p) = epilogue(A X(:, p)) for p in [0, n). A is rows x k, packed as A[j * pad8(rows) + r];
// bias (kBias*) has pad8(rows) entries; M (kMask) has the layout of Y with leading dim ldm.
void gemm_cols_avx2(const float* A, int rows, int k, const float* X, std::ptrdiff_t ldx, int n,
                    float* Y, std::ptrdiff_t ldy, Epilogue epi, const float* bias, const float* M,
                    std::ptrdiff_t ldm);

// G += D X^T and gb += rowsum(D): D is rows x n (leading dim ldd), X is k x n (leading dim ldx),
// G is rows x k packed as G[j * pad8(rows) + r], gb (nullptr: skipped) has pad8(rows) entries.
// Points are summed in order (the result does not depend on anything but the inputs).
void outer_acc_avx2(const float* D, std::ptrdiff_t ldd, int rows, const float* X,
                    std::ptrdiff_t ldx, int k, int n, float* G, float* gb);

// gb += rowsum(D), D rows x n (leading dim ldd), gb with pad8(rows) entries; points in order.
void rowsum_acc_avx2(const float* D, std::ptrdiff_t ldd, int rows, int n, float* gb);

// The same three on 16-wide vectors (mlp_avx512.cpp); the same results, bit for bit.
void gemm_cols_avx512(const float* A, int rows, int k, const float* X, std::ptrdiff_t ldx, int n,
                      float* Y, std::ptrdiff_t ldy, Epilogue epi, const float* bias, const float* M,
                      std::ptrdiff_t ldm);
void outer_acc_avx512(const float* D, std::ptrdiff_t ldd, int rows, const float* X,
                      std::ptrdiff_t ldx, int k, int n, float* G, float* gb);
void rowsum_acc_avx512(const float* D, std::ptrdiff_t ldd, int rows, int n, float* gb);

// True when the CPU has AVX2 and FMA; AVX-512F as well.
bool cpu_has_avx2_fma();
bool cpu_has_avx512();

// Which implementation mlp_forward / mlp_backward<float> use. kAuto: AVX-512 when the CPU has
// it and KS_MLP_NO_AVX512 is not set, else AVX2 when the CPU has AVX2+FMA and KS_MLP_NO_AVX2 is
// not set, Eigen otherwise; kAvx2: the AVX2 kernels even on an AVX-512 CPU. The setter is for
// tests and benchmarks (not thread-safe against concurrent MLP calls).
enum class Path { kAuto, kEigen, kAvx2, kAvx512 };
void set_path(Path p);
// use_avx2(): the hand-written kernels (either width) rather than Eigen; use_avx512(): of those,
// the 16-wide ones.
bool use_avx2();
bool use_avx512();

// The kernels above of the width use_avx512() picks (callers check use_avx2() first).
inline void gemm_cols(const float* A, int rows, int k, const float* X, std::ptrdiff_t ldx, int n,
                      float* Y, std::ptrdiff_t ldy, Epilogue epi, const float* bias, const float* M,
                      std::ptrdiff_t ldm) {
  if (use_avx512())
    gemm_cols_avx512(A, rows, k, X, ldx, n, Y, ldy, epi, bias, M, ldm);
  else
    gemm_cols_avx2(A, rows, k, X, ldx, n, Y, ldy, epi, bias, M, ldm);
}
inline void outer_acc(const float* D, std::ptrdiff_t ldd, int rows, const float* X,
                      std::ptrdiff_t ldx, int k, int n, float* G, float* gb) {
  if (use_avx512())
    outer_acc_avx512(D, ldd, rows, X, ldx, k, n, G, gb);
  else
    outer_acc_avx2(D, ldd, rows, X, ldx, k, n, G, gb);
}
inline void rowsum_acc(const float* D, std::ptrdiff_t ldd, int rows, int n, float* gb) {
  if (use_avx512())
    rowsum_acc_avx512(D, ldd, rows, n, gb);
  else
    rowsum_acc_avx2(D, ldd, rows, n, gb);
}

}  // namespace ks::mlp_kernels
