// The AVX2+FMA decoder kernels against the Eigen path (float), on the trainer's shapes and odd
// ones (partial vectors, tail points, 1-wide outputs).
#include <gtest/gtest.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/error.hpp"
#include "reconstruct/mlp.hpp"
#include "reconstruct/mlp_kernels.hpp"

namespace ks {
namespace {

namespace mk = mlp_kernels;

struct PathGuard {
  explicit PathGuard(mk::Path p) { mk::set_path(p); }
  ~PathGuard() { mk::set_path(mk::Path::kAuto); }
};

// Every entry of A drawn from u, in memory order.
template <class M, class Dist, class Rng>
void fill_uniform(M& A, Dist& u, Rng& rng) {
  for (Eigen::Index i = 0; i < A.size(); ++i) A.data()[i] = u(rng);
}

struct Result {
  Mlp::Mat Y, dX;
  MlpGrads g;
};

Result run(const Mlp& m, const Mlp::Mat& X, const Mlp::Mat& dY, mk::Path path, bool with_dx) {
  PathGuard guard(path);
  Result r;
  MlpCache cache;
  mlp_forward(m, X, cache, r.Y);
  r.g.zero_like(m);
  mlp_backward(m, cache, dY, r.g, with_dx ? &r.dX : nullptr);
  return r;
}

// max |a - b| relative to max |b| (the sums have mixed signs: element-wise relative error is
// meaningless where a sum nearly cancels).
double rel_diff(const Mlp::Mat& a, const Mlp::Mat& b) {
  EXPECT_EQ(a.rows(), b.rows());
  EXPECT_EQ(a.cols(), b.cols());
  if (a.rows() != b.rows() || a.cols() != b.cols()) return 1e30;
  const double scale = std::max(double(b.cwiseAbs().maxCoeff()), 1e-30);
  return double((a - b).cwiseAbs().maxCoeff()) / scale;
}

// An MLP of these layer widths with small random biases, and an input and output gradient of n
// points drawn from seed.
struct Case {
  Mlp m;
  Mlp::Mat X, dY;
  Case(const std::vector<int>& dims, int n, uint64_t seed)
      : X(dims.front(), n), dY(dims.back(), n) {
    m.init(dims, seed, 0.5f);
    std::mt19937_64 rng(seed + 1);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    for (auto& b : m.b)
      for (int i = 0; i < b.size(); ++i) b(i) = 0.1f * u(rng);
    fill_uniform(X, u, rng);
    fill_uniform(dY, u, rng);
  }
};

void compare(const std::vector<int>& dims, int n, uint64_t seed) {
  SCOPED_TRACE(::testing::Message() << "dims in=" << dims.front() << " hidden=" << dims[1]
                                    << " out=" << dims.back() << " n=" << n);
  const Case c(dims, n, seed);
  const Mlp& m = c.m;
  const Mlp::Mat &X = c.X, &dY = c.dY;
  const Result ref = run(m, X, dY, mk::Path::kEigen, true);
  const Result got = run(m, X, dY, mk::Path::kAvx2, true);
  const double tol = 1e-5;
  EXPECT_LT(rel_diff(got.Y, ref.Y), tol);
  EXPECT_LT(rel_diff(got.dX, ref.dX), tol);
  for (size_t l = 0; l < m.W.size(); ++l) {
    SCOPED_TRACE(::testing::Message() << "layer " << l);
    EXPECT_LT(rel_diff(got.g.W[l], ref.g.W[l]), tol);
    EXPECT_LT(rel_diff(got.g.b[l], ref.g.b[l]), tol);
  }
  // Without dX the weight gradients are the same.
  const Result nodx = run(m, X, dY, mk::Path::kAvx2, false);
  for (size_t l = 0; l < m.W.size(); ++l) {
    EXPECT_EQ(nodx.g.W[l], got.g.W[l]);
    EXPECT_EQ(nodx.g.b[l], got.g.b[l]);
  }
}

#define SKIP_WITHOUT_AVX2() \
  if (!mk::cpu_has_avx2_fma()) GTEST_SKIP() << "CPU has no AVX2/FMA"

TEST(MlpKernels, TrainerShapesMatchEigen) {
  SKIP_WITHOUT_AVX2();
  for (int n : {1, 7, 2049, 5000}) {
    compare({96, 64, 64, 9}, n, 11);
    compare({96, 64, 64, 3}, n, 12);
  }
}

TEST(MlpKernels, OddShapesMatchEigen) {
  SKIP_WITHOUT_AVX2();
  for (int n : {1, 7, 2049}) {
    compare({5, 7, 7, 1}, n, 21);
    compare({5, 64, 3}, n, 22);
    compare({96, 7, 9}, n, 23);
    compare({5, 7, 64, 64, 9}, n, 24);
    compare({17, 24, 1}, n, 25);
  }
}

#define SKIP_WITHOUT_AVX512() \
  if (!mk::cpu_has_avx512()) GTEST_SKIP() << "CPU has no AVX-512"

// The AVX-512 kernels give the AVX2 kernels' bits through the whole MLP, forward and backward.
TEST(MlpKernels, Avx512GivesTheAvx2Bits) {
  SKIP_WITHOUT_AVX512();
  const std::vector<std::vector<int>> shapes = {{96, 32, 32, 9}, {96, 32, 32, 3}, {96, 64, 64, 9},
                                                {5, 7, 7, 1},    {17, 24, 1},     {5, 40, 40, 9}};
  for (const auto& dims : shapes)
    for (int n : {1, 7, 13, 2049}) {
      SCOPED_TRACE(::testing::Message() << "hidden=" << dims[1] << " n=" << n);
      const Case c(dims, n, 41);
      const Result a = run(c.m, c.X, c.dY, mk::Path::kAvx2, true);
      const Result b = run(c.m, c.X, c.dY, mk::Path::kAvx512, true);
      EXPECT_EQ(b.Y, a.Y);
      EXPECT_EQ(b.dX, a.dX);
      for (size_t l = 0; l < c.m.W.size(); ++l) {
        EXPECT_EQ(b.g.W[l], a.g.W[l]) << l;
        EXPECT_EQ(b.g.b[l], a.g.b[l]) << l;
      }
    }
}

// The kernels one by one, on strided operands, every epilogue, rows that end inside a vector of
// either width and results accumulated onto what is there: the two widths agree bit for bit and
// leave everything outside the output alone.
TEST(MlpKernels, Avx512KernelsGiveTheAvx2Bits) {
  SKIP_WITHOUT_AVX512();
  std::mt19937_64 rng(51);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  auto random = [&](size_t count) {
    std::vector<float> v(count);
    for (float& x : v) x = u(rng);
    return v;
  };
  for (int rows : {1, 5, 8, 16, 24, 32, 40, 64})
    for (int k : {1, 3, 9, 32, 33})
      for (int n : {1, 11, 12, 13, 40}) {
        SCOPED_TRACE(::testing::Message() << "rows=" << rows << " k=" << k << " n=" << n);
        const int lda = mk::pad8(rows);
        const std::ptrdiff_t ldx = k + 3, ldy = rows + 5, ldm = rows + 2;
        std::vector<float> A = random(size_t(lda) * k), bias = random(size_t(lda));
        for (int j = 0; j < k; ++j)  // packed weights: the pad rows are zero
          for (int r = rows; r < lda; ++r) A[size_t(j) * lda + r] = 0.f;
        const std::vector<float> X = random(size_t(ldx) * n), M = random(size_t(ldm) * n);
        const std::vector<float> Y0 = random(size_t(ldy) * n);
        for (mk::Epilogue e : {mk::Epilogue::kNone, mk::Epilogue::kBias, mk::Epilogue::kBiasRelu,
                               mk::Epilogue::kMask, mk::Epilogue::kAdd}) {
          std::vector<float> y2 = Y0, y5 = Y0;
          mk::gemm_cols_avx2(A.data(), rows, k, X.data(), ldx, n, y2.data(), ldy, e, bias.data(),
                             M.data(), ldm);
          mk::gemm_cols_avx512(A.data(), rows, k, X.data(), ldx, n, y5.data(), ldy, e, bias.data(),
                               M.data(), ldm);
          EXPECT_EQ(y5, y2) << "epilogue " << int(e);
        }
        // G (rows x k, packed) += D X^T and the bias gradient, onto earlier values.
        const std::ptrdiff_t ldd = rows + 1;
        const std::vector<float> D = random(size_t(ldd) * n);
        std::vector<float> G0 = random(size_t(lda) * k), gb0 = random(size_t(lda));
        for (int j = 0; j < k; ++j)
          for (int r = rows; r < lda; ++r) G0[size_t(j) * lda + r] = 0.f;
        for (int r = rows; r < lda; ++r) gb0[size_t(r)] = 0.f;
        std::vector<float> g2 = G0, g5 = G0, b2 = gb0, b5 = gb0;
        mk::outer_acc_avx2(D.data(), ldd, rows, X.data(), ldx, k, n, g2.data(), b2.data());
        mk::outer_acc_avx512(D.data(), ldd, rows, X.data(), ldx, k, n, g5.data(), b5.data());
        EXPECT_EQ(g5, g2);
        EXPECT_EQ(b5, b2);
        mk::rowsum_acc_avx2(D.data(), ldd, rows, n, b2.data());
        mk::rowsum_acc_avx512(D.data(), ldd, rows, n, b5.data());
        EXPECT_EQ(b5, b2);
      }
}

// Gradients accumulate into g (as the Eigen path does) and do not depend on the thread count.
TEST(MlpKernels, AccumulatesAndIsThreadCountIndependent) {
  SKIP_WITHOUT_AVX2();
  PathGuard guard(mk::Path::kAvx2);
  Mlp m;
  m.init({96, 64, 64, 9}, 3, 0.5f);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  const int n = 5000;
  Mlp::Mat X(96, n), dY(9, n);
  fill_uniform(X, u, rng);
  fill_uniform(dY, u, rng);
  MlpCache cache;
  Mlp::Mat Y, dX;
  mlp_forward(m, X, cache, Y);
  MlpGrads g1, g2;
  g1.zero_like(m);
  mlp_backward(m, cache, dY, g1, &dX);
  g2 = g1;
  mlp_backward(m, cache, dY, g2, &dX);
  for (size_t l = 0; l < m.W.size(); ++l) EXPECT_LT(rel_diff(g2.W[l], Mlp::Mat(2 * g1.W[l])), 1e-6);
#ifdef _OPENMP
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  MlpGrads g3;
  g3.zero_like(m);
  Mlp::Mat dX1;
  mlp_backward(m, cache, dY, g3, &dX1);
  omp_set_num_threads(threads);
  for (size_t l = 0; l < m.W.size(); ++l) {
    EXPECT_EQ(g3.W[l], g1.W[l]);
    EXPECT_EQ(g3.b[l], g1.b[l]);
  }
  EXPECT_EQ(dX1, dX);
#endif
}

// An input the cache does not keep (the decoder's features): the backward reads the caller's X
// and everything comes out bit for bit as with the copy; without X the backward refuses, and a
// strided X cannot be borrowed.
TEST(MlpKernels, InputNotKeptGivesTheSameResults) {
  for (mk::Path path : {mk::Path::kEigen, mk::Path::kAvx2}) {
    if (path == mk::Path::kAvx2 && !mk::cpu_has_avx2_fma()) continue;
    PathGuard guard(path);
    Mlp m;
    m.init({96, 32, 32, 9}, 5, 0.5f);
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    const int n = 3001;
    Mlp::Mat X(96, n), dY(9, n);
    fill_uniform(X, u, rng);
    fill_uniform(dY, u, rng);
    MlpCache kept, borrowed;
    Mlp::Mat Y1, Y2, dX1, dX2;
    mlp_forward(m, X, kept, Y1);
    mlp_forward(m, X, borrowed, Y2, false);
    EXPECT_EQ(borrowed.act[0].cols(), 0);
    EXPECT_EQ(Y1, Y2);
    MlpGrads g1, g2;
    g1.zero_like(m);
    g2.zero_like(m);
    mlp_backward(m, kept, dY, g1, &dX1);
    mlp_backward(m, borrowed, dY, g2, &dX2, X.data());
    EXPECT_EQ(dX1, dX2);
    for (size_t l = 0; l < m.W.size(); ++l) {
      EXPECT_EQ(g1.W[l], g2.W[l]);
      EXPECT_EQ(g1.b[l], g2.b[l]);
    }
    EXPECT_THROW(mlp_backward(m, borrowed, dY, g2, &dX2), Error);
    Mlp::Mat big(100, n);
    big.setZero();
    EXPECT_THROW(mlp_forward(m, big.topRows(96), borrowed, Y2, false), Error);
  }
  // The double path (the finite-difference tests' precision) the same way.
  MlpT<double> md;
  md.init({7, 5, 3}, 2, 0.5);
  MlpT<double>::Mat X = MlpT<double>::Mat::Random(7, 50), dY = MlpT<double>::Mat::Random(3, 50);
  MlpCacheT<double> kept, borrowed;
  MlpT<double>::Mat Y1, Y2, dX1, dX2;
  mlp_forward(md, X, kept, Y1);
  mlp_forward(md, X, borrowed, Y2, false);
  EXPECT_EQ(Y1, Y2);
  MlpGradsT<double> g1, g2;
  g1.zero_like(md);
  g2.zero_like(md);
  mlp_backward(md, kept, dY, g1, &dX1);
  mlp_backward(md, borrowed, dY, g2, &dX2, X.data());
  EXPECT_EQ(dX1, dX2);
  EXPECT_EQ(g1.W[0], g2.W[0]);
}

// The decoder's two heads on one input: a geometry MLP (96 -> 32 -> 32 -> 9) and a second one of
// the given shape, with random inputs and output gradients.
struct TwoHeads {
  Mlp a, b;
  Mlp::Mat X, dYa, dYb;
  TwoHeads(const std::vector<int>& b_dims, uint64_t seed, int n) {
    a.init({96, 32, 32, 9}, 7, 0.5f);
    b.init(b_dims, 8, 0.5f);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    X.resize(96, n), dYa.resize(9, n), dYb.resize(b_dims.back(), n);
    fill_uniform(X, u, rng);
    fill_uniform(dYa, u, rng);
    fill_uniform(dYb, u, rng);
  }
};

// Two MLPs on one input (the decoder): the second's input gradient added to the first's as it
// is written is the sum of the two, bit for bit, on both paths; a gradient of the wrong shape to
// add to is refused.
TEST(MlpKernels, InputGradientAddedInPlace) {
  for (mk::Path path : {mk::Path::kEigen, mk::Path::kAvx2}) {
    if (path == mk::Path::kAvx2 && !mk::cpu_has_avx2_fma()) continue;
    PathGuard guard(path);
    const TwoHeads h({96, 32, 3}, 9, 2051);
    const Mlp &a = h.a, &b = h.b;
    const Mlp::Mat &X = h.X, &dYa = h.dYa, &dYb = h.dYb;
    const int n = int(X.cols());
    MlpCache ca, cb;
    Mlp::Mat Ya, Yb, dXa, dXb, dX;
    mlp_forward(a, X, ca, Ya, false);
    mlp_forward(b, X, cb, Yb, false);
    MlpGrads ga, gb, ga2, gb2;
    ga.zero_like(a), gb.zero_like(b), ga2.zero_like(a), gb2.zero_like(b);
    mlp_backward(a, ca, dYa, ga, &dXa, X.data());
    mlp_backward(b, cb, dYb, gb, &dXb, X.data());
    mlp_backward(a, ca, dYa, ga2, &dX, X.data());
    mlp_backward(b, cb, dYb, gb2, &dX, X.data(), true);
    const Mlp::Mat sum = dXa + dXb;
    EXPECT_EQ(dX, sum);
    for (size_t l = 0; l < b.W.size(); ++l) EXPECT_EQ(gb2.W[l], gb.W[l]);
    Mlp::Mat wrong(96, n - 1);
    EXPECT_THROW(mlp_backward(b, cb, dYb, gb2, &wrong, X.data(), true), Error);
  }
}

// The pair (the decoder's two heads a few points at a time through both) against the two MLPs
// one after the other: outputs, weight gradients and the summed input gradient bit for bit, on
// both paths and on 1 and 2 threads (several blocks, a tail sub-block); mismatched MLPs refused.
TEST(MlpKernels, PairGivesTheSameBitsAsTwoPasses) {
  for (mk::Path path : {mk::Path::kEigen, mk::Path::kAvx2}) {
    if (path == mk::Path::kAvx2 && !mk::cpu_has_avx2_fma()) continue;
    PathGuard guard(path);
    const TwoHeads h({96, 32, 32, 3}, 10, 4133);
    const Mlp &a = h.a, &b = h.b;
    const Mlp::Mat &X = h.X, &dYa = h.dYa, &dYb = h.dYb;
    const int n = int(X.cols());
    MlpCache ca, cb;
    Mlp::Mat Ya, Yb, dX;
    mlp_forward(a, X, ca, Ya, false);
    mlp_forward(b, X, cb, Yb, false);
    MlpGrads ga, gb;
    ga.zero_like(a), gb.zero_like(b);
    mlp_backward(a, ca, dYa, ga, &dX, X.data());
    mlp_backward(b, cb, dYb, gb, &dX, X.data(), true);
#ifdef _OPENMP
    const int saved = omp_get_max_threads();
#endif
    for (int threads : {1, 2}) {
#ifdef _OPENMP
      omp_set_num_threads(threads);
#endif
      SCOPED_TRACE(::testing::Message() << "threads " << threads);
      MlpCache pa, pb;
      Mlp::Mat Pa, Pb, pdX;
      mlp_forward_pair(a, b, X, pa, Pa, pb, Pb);
      EXPECT_EQ(Pa, Ya);
      EXPECT_EQ(Pb, Yb);
      MlpGrads qa, qb;
      qa.zero_like(a), qb.zero_like(b);
      mlp_backward_pair(a, pa, dYa, qa, b, pb, dYb, qb, pdX, X.data());
      EXPECT_EQ(pdX, dX);
      for (size_t l = 0; l < a.W.size(); ++l) {
        EXPECT_EQ(qa.W[l], ga.W[l]);
        EXPECT_EQ(qa.b[l], ga.b[l]);
        EXPECT_EQ(qb.W[l], gb.W[l]);
        EXPECT_EQ(qb.b[l], gb.b[l]);
      }
      if (path == mk::Path::kAvx2) {
        const Mlp::Mat short_dY = dYb.leftCols(n - 1);
        EXPECT_THROW(mlp_backward_pair(a, pa, dYa, qa, b, pb, short_dY, qb, pdX, X.data()), Error);
      }
    }
#ifdef _OPENMP
    omp_set_num_threads(saved);
#endif
  }
}

// An empty batch gives empty outputs and leaves the gradients as they were (both paths).
TEST(MlpKernels, EmptyBatch) {
  for (mk::Path path : {mk::Path::kEigen, mk::Path::kAvx2}) {
    if (path == mk::Path::kAvx2 && !mk::cpu_has_avx2_fma()) continue;
    PathGuard guard(path);
    Mlp m;
    m.init({96, 64, 64, 9}, 3, 0.5f);
    Mlp::Mat X(96, 0), dY(9, 0), Y, dX;
    MlpCache cache;
    mlp_forward(m, X, cache, Y);
    EXPECT_EQ(Y.rows(), 9);
    EXPECT_EQ(Y.cols(), 0);
    MlpGrads g;
    g.zero_like(m);
    g.W[0](1, 2) = 0.5f;
    mlp_backward(m, cache, dY, g, &dX);
    EXPECT_EQ(dX.rows(), 96);
    EXPECT_EQ(dX.cols(), 0);
    EXPECT_EQ(g.W[0](1, 2), 0.5f);
    EXPECT_EQ(g.W[1].squaredNorm(), 0.f);
  }
}

// The layers after the first (mlp_forward_tail / mlp_backward_tail, for a first layer computed
// elsewhere) of two MLPs whose first-layer gradients share one buffer: the outputs and the later
// layers' gradients of the whole MLPs, bit for bit, the first layer's bias gradient too, its
// weight gradient left alone; and d0 X^T is the whole backward's first-layer weight gradient.
TEST(MlpKernels, TailMatchesTheWholeMlps) {
  SKIP_WITHOUT_AVX2();
  PathGuard guard(mk::Path::kAvx2);
  const int n = 150, in = 24;
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Mlp a, b;
  a.init({in, 16, 16, 9}, 1, 0.5f);
  b.init({in, 8, 8, 3}, 2, 0.5f);
  for (Mlp* m : {&a, &b})
    for (auto& bias : m->b)
      for (int i = 0; i < bias.size(); ++i) bias(i) = 0.1f * u(rng);
  Mlp::Mat X(in, n), dYa(9, n), dYb(3, n);
  fill_uniform(X, u, rng);
  fill_uniform(dYa, u, rng);
  fill_uniform(dYb, u, rng);
  MlpCache ca, cb;
  Mlp::Mat Ya, Yb;
  mlp_forward(a, X, ca, Ya);
  mlp_forward(b, X, cb, Yb);
  MlpGrads ga, gb;
  ga.zero_like(a), gb.zero_like(b);
  mlp_backward(a, ca, dYa, ga, nullptr);
  mlp_backward(b, cb, dYb, gb, nullptr);
  // The tails, from the whole forwards' first-layer outputs.
  MlpCache ta, tb;
  Mlp::Mat Ta, Tb;
  mlp_tail_buffers(a, n, ta, Ta);
  mlp_tail_buffers(b, n, tb, Tb);
  ta.act[1] = ca.act[1], tb.act[1] = cb.act[1];
  const Mlp* ms[2] = {&a, &b};
  MlpCache* cs[2] = {&ta, &tb};
  Mlp::Mat* Ys[2] = {&Ta, &Tb};
  mlp_forward_tail(ms, cs, Ys, 2);
  EXPECT_EQ(Ta, Ya);
  EXPECT_EQ(Tb, Yb);
  MlpGrads ha, hb;
  ha.zero_like(a), hb.zero_like(b);
  const int H = 24;  // 16 + 8 rows of d0 a point
  std::vector<float> d0(size_t(H) * n, 7.f);
  const MlpCache* ccs[2] = {&ta, &tb};
  const Mlp::Mat* dYs[2] = {&dYa, &dYb};
  MlpGrads* gs[2] = {&ha, &hb};
  float* d0s[2] = {d0.data(), d0.data() + 16};
  mlp_backward_tail(ms, ccs, dYs, gs, d0s, H, 2);
  for (size_t l = 1; l < a.W.size(); ++l) {
    EXPECT_EQ(ha.W[l], ga.W[l]) << l;
    EXPECT_EQ(ha.b[l], ga.b[l]) << l;
    EXPECT_EQ(hb.W[l], gb.W[l]) << l;
    EXPECT_EQ(hb.b[l], gb.b[l]) << l;
  }
  EXPECT_LT(rel_diff(ha.b[0], ga.b[0]), 1e-6);
  EXPECT_LT(rel_diff(hb.b[0], gb.b[0]), 1e-6);
  EXPECT_EQ(ha.W[0].cwiseAbs().maxCoeff(), 0.f);
  const Eigen::Map<const Mlp::Mat, 0, Eigen::OuterStride<>> D(d0.data(), H, n,
                                                              Eigen::OuterStride<>(H));
  EXPECT_LT(rel_diff(D.topRows(16) * X.transpose(), ga.W[0]), 1e-5);
  EXPECT_LT(rel_diff(D.bottomRows(8) * X.transpose(), gb.W[0]), 1e-5);
  // Buffers the tail's sizing did not make are refused.
  MlpCache stale;
  MlpCache* bad[1] = {&stale};
  EXPECT_THROW(mlp_forward_tail(ms, bad, Ys, 1), Error);
}

}  // namespace
}  // namespace ks
