#pragma once
// Hand-written AVX2+FMA kernels for the float decoder MLP (internal to reconstruct/mlp.cpp and
// its tests). Plain pointers, no Eigen: mlp_avx2.cpp is compiled with per-function target
// attributes, and Eigen code instantiated there with a different ISA would be an ODR hazard.
//
// All matrices are column-major with one point per column ("point-major": a point's values are
// contiguous); ld* is the distance between two points' columns in floats. Weight operands are
// packed with their row count padded to a multiple of 8 (pad rows are zero), 32-byte aligned.
#include <cstddef>

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

// True when the CPU has AVX2 and FMA.
bool cpu_has_avx2_fma();

// Which implementation mlp_forward / mlp_backward<float> use. kAuto: AVX2 when the CPU has
// AVX2+FMA and KS_MLP_NO_AVX2 is not set, Eigen otherwise. The setter is for tests and
// benchmarks (not thread-safe against concurrent MLP calls).
enum class Path { kAuto, kEigen, kAvx2 };
void set_path(Path p);
bool use_avx2();

}  // namespace ks::mlp_kernels
