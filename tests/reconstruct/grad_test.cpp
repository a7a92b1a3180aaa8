// Finite-difference gradient checks (double precision) for the triplane, MLP, SSIM, L1 and
// Laplacian pieces of the avatar fit.
#include <gtest/gtest.h>

#include <omp.h>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "core/error.hpp"
#include "grad_check.hpp"
#include "reconstruct/losses.hpp"
#include "reconstruct/mlp.hpp"
#include "reconstruct/triplane.hpp"

namespace ks {

namespace {

using test::expect_grad;
using test::randv;

// A float triplane over the box [-1, 1]^3 (res x res, C channels, noise from init_seed) and n
// points with their upstream feature gradients: the points' coordinates drawn from
// U(plo, phi) point by point, then the gradients from U(dlo, dhi).
struct TriplaneScene {
  Triplane tp;
  int n = 0;
  std::vector<float> xs, ys, zs, dfeats;
};
TriplaneScene triplane_scene(uint64_t seed, int res, int C, uint64_t init_seed, int n, float plo,
                             float phi, float dlo, float dhi) {
  std::mt19937_64 rng(seed);
  TriplaneScene S;
  const float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
  S.tp.init(res, C, lo, hi, init_seed, 0.5f);
  S.n = n;
  S.xs.resize(size_t(n)), S.ys.resize(size_t(n)), S.zs.resize(size_t(n));
  S.dfeats.resize(size_t(n) * S.tp.feature_dim());
  std::uniform_real_distribution<float> u(plo, phi), d(dlo, dhi);
  for (int i = 0; i < n; ++i)
    S.xs[size_t(i)] = u(rng), S.ys[size_t(i)] = u(rng), S.zs[size_t(i)] = u(rng);
  for (auto& v : S.dfeats) v = d(rng);
  return S;
}

}  // namespace

TEST(ReconstructGrad, TriplaneMatchesFiniteDifferences) {
  std::mt19937_64 rng(1);
  TriplaneT<double> tp;
  const double lo[3] = {-1, -0.5, -2}, hi[3] = {1, 1.5, 0};
  tp.init(8, 5, lo, hi, 3, 0.5);
  const int n = 40;
  auto xs = randv(n, rng, -1.2, 1.2), ys = randv(n, rng, -0.6, 1.6), zs = randv(n, rng, -2.1, 0.1);
  auto wts = randv(size_t(n) * tp.feature_dim(), rng);
  auto f = [&](const std::vector<double>& planes) {
    TriplaneT<double> t2 = tp;
    t2.planes = planes;
    std::vector<double> feats(size_t(n) * t2.feature_dim());
    triplane_forward(t2, xs.data(), ys.data(), zs.data(), n, feats.data());
    double s = 0;
    for (size_t i = 0; i < feats.size(); ++i) s += wts[i] * feats[i];
    return s;
  };
  std::vector<double> g(tp.size(), 0.0);
  triplane_backward(tp, xs.data(), ys.data(), zs.data(), n, wts.data(), g.data());
  // Concentrate the checks on touched texels: check all entries of a small plane.
  expect_grad(f, tp.planes, g, 1e-6, 1e-6, 300);
  // Interpolation reproduces a texel exactly at the grid point (box corner).
  std::vector<double> feats(tp.feature_dim());
  double x = lo[0], y = lo[1], z = lo[2];
  triplane_forward(tp, &x, &y, &z, 1, feats.data());
  EXPECT_DOUBLE_EQ(feats[0], tp.planes[0]);
}

// The marked texels hold every texel triplane_backward writes for the same points (with points
// outside the box, clamped to its border), and their ranges cover exactly the marked texels.
TEST(ReconstructGrad, TriplaneMarkedTexelsHoldEveryWrittenTexel) {
  const TriplaneScene S = triplane_scene(10, 20, 4, 3, 60, -1.2f, 0.3f, 0.5f, 1.f);
  const Triplane& tp = S.tp;
  const int n = S.n;
  const std::vector<float>&xs = S.xs, &ys = S.ys, &zs = S.zs, &dfeats = S.dfeats;
  std::vector<float> g(tp.size(), 0.f);
  triplane_backward(tp, xs.data(), ys.data(), zs.data(), n, dfeats.data(), g.data());
  std::vector<uint8_t> marked;
  triplane_mark_texels(tp, xs.data(), ys.data(), zs.data(), n, &marked);
  ASSERT_EQ(marked.size(), tp.size() / 4);
  size_t n_marked = 0, n_written = 0;
  for (size_t t = 0; t < marked.size(); ++t) {
    bool written = false;
    for (int c = 0; c < 4; ++c) written |= g[t * 4 + size_t(c)] != 0.f;
    if (written) {
      EXPECT_EQ(marked[t], 1) << t;
    }
    n_marked += marked[t];
    n_written += written;
  }
  EXPECT_GT(n_written, 0u);
  EXPECT_LT(n_marked, marked.size());  // the points fill only part of the box
  const auto ranges = texel_ranges(marked, 4);
  std::vector<uint8_t> covered(marked.size(), 0);
  size_t prev_end = 0;
  for (const auto& [b, e] : ranges) {
    EXPECT_LT(b, e);
    EXPECT_TRUE(b == 0 || b > prev_end);  // disjoint, sorted, neighbours joined
    EXPECT_EQ(b % 4, 0u);
    EXPECT_EQ(e % 4, 0u);
    for (size_t t = b / 4; t < e / 4; ++t) covered[t] = 1;
    prev_end = e;
  }
  EXPECT_EQ(covered, marked);
}

// The threaded backward (points binned into row stripes) is bit-identical for 1 and 2 threads,
// and the adjoint of the forward.
TEST(ReconstructGrad, TriplaneBackwardIsThreadIndependent) {
  // 5000 points: above the parallel threshold.
  const TriplaneScene S = triplane_scene(9, 24, 6, 2, 5000, -1.1f, 1.1f, -1.1f, 1.1f);
  const Triplane& tp = S.tp;
  const int n = S.n;
  const std::vector<float>&xs = S.xs, &ys = S.ys, &zs = S.zs, &dfeats = S.dfeats;
  auto run = [&](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    std::vector<float> g(tp.size(), 0.f);
    triplane_backward(tp, xs.data(), ys.data(), zs.data(), n, dfeats.data(), g.data());
    omp_set_num_threads(saved);
    return g;
  };
  const auto g1 = run(1), g2 = run(2);
  EXPECT_EQ(g1, g2);
  // The features are linear in the planes (feats = A planes, g = A^T dfeats), so
  // g . planes = dfeats . feats.
  std::vector<float> feats(dfeats.size());
  triplane_forward(tp, xs.data(), ys.data(), zs.data(), n, feats.data());
  double lhs = 0, rhs = 0;
  for (size_t q = 0; q < g1.size(); ++q) lhs += double(g1[q]) * tp.planes[q];
  for (size_t q = 0; q < feats.size(); ++q) rhs += double(dfeats[q]) * feats[q];
  EXPECT_NEAR(lhs, rhs, 1e-3 * std::max(1.0, std::abs(rhs)));
}

// The backward's bins: each plane's points by stripe of texel rows, in index order within a
// stripe; bins made once give the same gradient as bins made per call, and bins of other points
// are refused.
TEST(ReconstructGrad, TriplaneBinsHoldThePointsByStripe) {
  const TriplaneScene S = triplane_scene(10, 40, 4, 3, 3000, -1.1f, 1.1f, -1.1f, 1.1f);
  const Triplane& tp = S.tp;
  const int n = S.n;
  const std::vector<float>&xs = S.xs, &ys = S.ys, &zs = S.zs, &dfeats = S.dfeats;
  const TriplaneBins B = triplane_bins(tp, xs.data(), ys.data(), zs.data(), n);
  ASSERT_EQ(B.order.size(), size_t(3) * n);
  ASSERT_EQ(B.start.size(), size_t(3) * (B.stripes + 1));
  // A point's texel in plane p, as the lookup computes it (u = x, v = y for plane 0, ...).
  auto texel = [&](int p, int i) {
    const float a = p == 2 ? ys[size_t(i)] : xs[size_t(i)];
    const float b = p == 0 ? ys[size_t(i)] : zs[size_t(i)];
    const int r = tp.res;
    auto cell = [&](float x, int axis) {
      const float t = std::clamp((x - tp.lo[axis]) / (tp.hi[axis] - tp.lo[axis]) * float(r - 1),
                                 0.f, float(r - 1));
      return std::min(int(t), r - 2);
    };
    return cell(b, p == 0 ? 1 : 2) * r + cell(a, p == 2 ? 1 : 0);
  };
  const int rows_per = (tp.res - 1 + B.stripes - 1) / B.stripes;
  for (int p = 0; p < 3; ++p) {
    const int* ord = B.order.data() + size_t(p) * n;
    const int* st = B.start.data() + size_t(p) * (B.stripes + 1);
    std::vector<int> seen(size_t(n), 0);
    for (int k = 0; k < n; ++k) ++seen[size_t(ord[k])];
    EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), n) << "plane " << p;
    EXPECT_EQ(st[0], 0);
    EXPECT_EQ(st[B.stripes], n);
    for (int s = 0; s < B.stripes; ++s)
      for (int k = st[s]; k < st[s + 1]; ++k) {
        const int row = texel(p, ord[k]) / tp.res;
        EXPECT_GE(row, s * rows_per);
        EXPECT_LT(row, (s + 1) * rows_per);
        if (k > st[s]) {
          EXPECT_LT(ord[k - 1], ord[k]);
        }
      }
  }
  std::vector<float> g1(tp.size(), 0.f), g2(tp.size(), 0.f);
  triplane_backward(tp, xs.data(), ys.data(), zs.data(), n, dfeats.data(), g1.data());
  triplane_backward(tp, xs.data(), ys.data(), zs.data(), n, dfeats.data(), g2.data(), &B);
  EXPECT_EQ(g1, g2);
  EXPECT_THROW(
      triplane_backward(tp, xs.data(), ys.data(), zs.data(), n - 1, dfeats.data(), g2.data(), &B),
      Error);
}

TEST(ReconstructGrad, MlpMatchesFiniteDifferences) {
  std::mt19937_64 rng(2);
  MlpT<double> m;
  m.init({6, 7, 5, 3}, 4, 0.5);
  const int n = 9;
  auto xin = randv(size_t(6) * n, rng);
  auto wts = randv(size_t(3) * n, rng);
  using Mat = MlpT<double>::Mat;
  auto eval = [&](const MlpT<double>& mm, const std::vector<double>& xv) {
    Eigen::Map<const Mat> X(xv.data(), 6, n);
    MlpCacheT<double> cache;
    Mat Y;
    mlp_forward(mm, X, cache, Y);
    double s = 0;
    for (int i = 0; i < Y.size(); ++i) s += wts[i] * Y.data()[i];
    return s;
  };
  Eigen::Map<const Mat> X(xin.data(), 6, n);
  MlpCacheT<double> cache;
  Mat Y;
  mlp_forward(m, X, cache, Y);
  Eigen::Map<const Mat> dY(wts.data(), 3, n);
  MlpGradsT<double> g;
  g.zero_like(m);
  Mat dX;
  mlp_backward(m, cache, dY, g, &dX);
  std::vector<double> p, gp;
  m.pack(p);
  g.pack(gp);
  expect_grad(
      [&](const std::vector<double>& pv) {
        MlpT<double> m2 = m;
        m2.unpack(pv);
        return eval(m2, xin);
      },
      p, gp, 1e-6, 1e-6, 1000);
  std::vector<double> gx(dX.data(), dX.data() + dX.size());
  expect_grad([&](const std::vector<double>& xv) { return eval(m, xv); }, xin, gx, 1e-6, 1e-6,
              1000);
}

TEST(ReconstructGrad, SsimMatchesFiniteDifferences) {
  std::mt19937_64 rng(4);
  const int w = 14, h = 13, c = 3;
  auto x = randv(size_t(w) * h * c, rng, 0, 1), y = randv(size_t(w) * h * c, rng, 0, 1);
  std::vector<double> g(x.size(), 0.0);
  ssim<double>(x.data(), y.data(), w, h, c, nullptr, 1.0, g.data());
  expect_grad(
      [&](const std::vector<double>& xv) {
        return ssim<double>(xv.data(), y.data(), w, h, c, nullptr, 0.0, nullptr);
      },
      x, g, 1e-6, 1e-5, 300);
  EXPECT_NEAR(ssim<double>(y.data(), y.data(), w, h, c, nullptr, 0.0, nullptr), 1.0, 1e-12);
}

// SSIM is computed only over the rectangle where the images differ, grown by two half-windows.
// Images that agree except in a small block: the value, map and gradient must match the whole
// picture's (forced by a 1e-9 difference in two corners), and the gradient the finite
// differences of the library's own forward, inside the rectangle, at its edge and outside it.
TEST(ReconstructGrad, SsimOverTheDifferingRectangle) {
  std::mt19937_64 rng(6);
  const int w = 40, h = 36, c = 3;
  auto y = randv(size_t(w) * h * c, rng, 0, 1);
  auto x = y;
  for (int yy = 14; yy <= 20; ++yy)
    for (int xx = 15; xx <= 22; ++xx)
      for (int k = 0; k < c; ++k)
        x[(size_t(yy) * w + xx) * c + k] = 0.5 * y[(size_t(yy) * w + xx) * c + k] + 0.3;
  std::vector<double> g(x.size(), 0.0), map;
  const double v = ssim<double>(x.data(), y.data(), w, h, c, &map, 1.0, g.data());
  EXPECT_LT(v, 1.0);
  auto xf = x;
  xf[0] += 1e-9;
  xf.back() += 1e-9;
  std::vector<double> gf(x.size(), 0.0), mapf;
  const double vf = ssim<double>(xf.data(), y.data(), w, h, c, &mapf, 1.0, gf.data());
  EXPECT_NEAR(v, vf, 1e-12);
  double sum = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    EXPECT_NEAR(map[i], mapf[i], 1e-9) << i;
    EXPECT_NEAR(g[i], gf[i], 1e-9) << i;
    sum += map[i];
  }
  EXPECT_NEAR(sum / double(map.size()), v, 1e-12);
  // Outside the rectangle grown by one half-window the map is exactly 1.
  EXPECT_EQ(map[(size_t(2) * w + 2) * c], 1.0);
  EXPECT_LT(map[(size_t(17) * w + 18) * c], 1.0);
  expect_grad(
      [&](const std::vector<double>& xv) {
        return ssim<double>(xv.data(), y.data(), w, h, c, nullptr, 0.0, nullptr);
      },
      x, g, 1e-6, 1e-5, 400);
}

// The float path (AVX2 rows where the CPU has them, parallel rows) gives the same bits on 1 and 2
// threads.
TEST(ReconstructGrad, SsimFloatSameOnOneAndTwoThreads) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  const int w = 160, h = 240, c = 3;
  std::vector<float> x(size_t(w) * h * c, 0.2f), y = x;
  for (int yy = 30; yy < 200; ++yy)
    for (int xx = 40; xx < 120; ++xx)
      for (int k = 0; k < c; ++k) {
        const size_t i = (size_t(yy) * w + xx) * c + k;
        y[i] = U(rng);
        x[i] = 0.7f * y[i] + 0.3f * U(rng);
      }
  const int saved = omp_get_max_threads();
  std::vector<float> g1(x.size(), 0.f), g2(x.size(), 0.f);
  omp_set_num_threads(1);
  const float v1 = ssim<float>(x.data(), y.data(), w, h, c, nullptr, -0.2f, g1.data());
  omp_set_num_threads(2);
  const float v2 = ssim<float>(x.data(), y.data(), w, h, c, nullptr, -0.2f, g2.data());
  omp_set_num_threads(saved);
  EXPECT_EQ(v1, v2);
  EXPECT_EQ(g1, g2);
}

TEST(ReconstructGrad, L1MatchesFiniteDifferences) {
  std::mt19937_64 rng(5);
  auto x = randv(50, rng), y = randv(50, rng);
  std::vector<double> g(50, 0.0);
  l1_loss<double>(x.data(), y.data(), 50, 0.8, g.data());
  expect_grad(
      [&](const std::vector<double>& xv) {
        return 0.8 * l1_loss<double>(xv.data(), y.data(), 50, 0.0, nullptr);
      },
      x, g);
}

TEST(ReconstructGrad, LaplacianMatchesFiniteDifferences) {
  // A strip of 8 vertices in two parts, a ring adjacency with chords.
  const int n = 8;
  std::vector<std::vector<int>> adj(n);
  for (int v = 0; v < n; ++v) adj[v] = {(v + 1) % n, (v + n - 1) % n, (v + 3) % n};
  std::vector<int> labels = {0, 0, 0, 1, 1, 1, 7, 7};
  std::mt19937_64 rng(6);
  auto a = randv(size_t(n) * 3, rng);
  for (auto mode : {LaplacianMode::kUniform, LaplacianMode::kSemantic}) {
    Laplacian lap = build_laplacian(adj, labels, mode, default_part_strengths());
    std::vector<double> g(a.size(), 0.0);
    const double L = laplacian_loss<double>(lap, a.data(), 3, 1.5, g.data());
    EXPECT_GT(L, 0.0);
    expect_grad(
        [&](const std::vector<double>& av) {
          return 1.5 * laplacian_loss<double>(lap, av.data(), 3, 0.0, nullptr);
        },
        a, g);
  }
  // Semantic mode ignores neighbours in other parts: vertex 2's only same-part neighbours are 0, 1.
  Laplacian sem = build_laplacian(adj, labels, LaplacianMode::kSemantic, default_part_strengths());
  for (int j = sem.offsets[2]; j < sem.offsets[3]; ++j) EXPECT_EQ(labels[sem.neighbours[j]], 0);
  Laplacian none = build_laplacian(adj, labels, LaplacianMode::kNone, default_part_strengths());
  EXPECT_EQ(laplacian_loss<double>(none, a.data(), 3, 1.0, nullptr), 0.0);
  EXPECT_THROW(parse_laplacian_mode("cotan"), std::exception);
}

// The gradient gathered per vertex (the transposed lists, in parallel) is the serial scatter's
// bit for bit, on lists that are not symmetric and hold repeats, the vertex itself and nothing;
// and the L1 loss's chunked sum does not depend on the thread count.
TEST(ReconstructGrad, LaplacianGatherIsTheScatterBitForBit) {
  const int n = 6000;
  std::mt19937_64 rng(9);
  std::uniform_int_distribution<int> pick(0, n - 1), count(0, 7), part(0, kNumParts - 1);
  std::vector<std::vector<int>> adj(n);
  std::vector<int> labels(n);
  for (int v = 0; v < n; ++v) {
    labels[size_t(v)] = part(rng) % 3;
    const int c = v % 97 == 0 ? 0 : count(rng);
    for (int k = 0; k < c; ++k) adj[size_t(v)].push_back(k == 3 ? v : pick(rng));
    if (c > 4) adj[size_t(v)].push_back(adj[size_t(v)][0]);
  }
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  const int saved = omp_get_max_threads();
  for (int dim : {3, 5})  // the trainer's channel count (a fixed-size path) and another
    for (auto mode : {LaplacianMode::kUniform, LaplacianMode::kSemantic}) {
      std::vector<float> a(size_t(n) * dim), base(a.size());
      for (auto& x : a) x = U(rng);
      for (auto& x : base) x = U(rng);
      const Laplacian gather = build_laplacian(adj, labels, mode, default_part_strengths());
      ASSERT_EQ(gather.in_offsets.size(), size_t(n) + 1);
      Laplacian scatter = gather;
      scatter.in_offsets.clear();
      scatter.in_from.clear();
      std::vector<float> g1 = base, g2 = base, g3 = base;
      const float v1 = laplacian_loss<float>(scatter, a.data(), dim, 0.7f, g1.data());
      omp_set_num_threads(1);
      const float v2 = laplacian_loss<float>(gather, a.data(), dim, 0.7f, g2.data());
      omp_set_num_threads(2);
      const float v3 = laplacian_loss<float>(gather, a.data(), dim, 0.7f, g3.data());
      omp_set_num_threads(saved);
      EXPECT_EQ(v1, v2);
      EXPECT_EQ(v2, v3);
      EXPECT_EQ(g1, g2);
      EXPECT_EQ(g1, g3);
    }
  const size_t m = 300001;  // several chunks and a partial one
  std::vector<float> x(m), y(m);
  for (size_t i = 0; i < m; ++i) x[i] = U(rng), y[i] = U(rng);
  std::vector<float> d1(m, 0.f), d2(m, 0.f);
  omp_set_num_threads(1);
  const float l1 = l1_loss<float>(x.data(), y.data(), m, 0.5f, d1.data());
  omp_set_num_threads(2);
  const float l2 = l1_loss<float>(x.data(), y.data(), m, 0.5f, d2.data());
  omp_set_num_threads(saved);
  EXPECT_EQ(l1, l2);
  EXPECT_EQ(d1, d2);
  double ref = 0;
  for (size_t i = 0; i < m; ++i) ref += std::abs(double(x[i] - y[i]));
  EXPECT_NEAR(l1, ref / double(m), 1e-6);
}

}  // namespace ks
