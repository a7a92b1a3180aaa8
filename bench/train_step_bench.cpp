// Google Benchmark: the per-step pieces of the avatar fit besides the rasterizer, at the CLI
// defaults: the decoder's decode + backward (the MLPs' first layers point by point or in texel
// space), the Adam step over the 512x512x32 triplane (25.2M parameters) and the
// triplane lookup forward / backward at the 2-level template's 165,378 vertices (numbered by
// the subdivision and along the trainer's Morton curve), the SSIM loss with
// its gradient at 512x768, and the semantic Laplacian of the 2-level template, on 1 and 2
// threads.
#include <benchmark/benchmark.h>
#include <omp.h>

#include <random>
#include <vector>

#include "body/body_model.hpp"
#include "mesh/morton.hpp"
#include "mesh/trimesh.hpp"
#include "reconstruct/adam.hpp"
#include "reconstruct/decoder.hpp"
#include "reconstruct/losses.hpp"
#include "reconstruct/texel_layer0.hpp"
#include "reconstruct/triplane.hpp"
#include "reconstruct/triplane_kernels.hpp"

namespace {

// Args: parameters, threads.
void BM_AdamStep(benchmark::State& st) {
  const size_t n = size_t(st.range(0));
  std::vector<float> p(n), g(n);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  for (size_t i = 0; i < n; ++i) p[i] = U(rng), g[i] = 1e-3f * U(rng);
  ks::Adam adam;
  adam.total_steps = 1000;
  adam.add_group("triplane", &p, &g, 2e-2f);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(1)));
  for (auto _ : st) {
    adam.step();
    benchmark::DoNotOptimize(p.data());
  }
  omp_set_num_threads(saved);
  st.counters["params/s"] =
      benchmark::Counter(double(st.iterations()) * double(n), benchmark::Counter::kIsRate);
}

// The lookup points of a training step: the default body's template subdivided twice (165,378
// vertices) in a box padded as the decoder pads it, numbered as the subdivision numbers them
// (ordered = 0) or as the trainer does (1: along a Morton curve, mesh/morton.hpp).
struct TriplaneFixture {
  ks::Triplane tp;
  std::vector<float> xs, ys, zs, feats, dfeats, dplanes;
  int n = 0;
  explicit TriplaneFixture(bool ordered) {
    const ks::BodyModel& body = ks::default_body_model();
    const ks::Subdivision sub = ks::subdivide(ks::TriMesh{body.v_template, body.faces}, 2);
    const Eigen::MatrixXd& V = sub.mesh.V;
    n = int(V.rows());
    float lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = float(V.col(k).minCoeff() - 0.11), hi[k] = float(V.col(k).maxCoeff() + 0.11);
    }
    tp.init(512, 32, lo, hi, 1);
    xs.resize(size_t(n)), ys.resize(size_t(n)), zs.resize(size_t(n));
    for (int i = 0; i < n; ++i)
      xs[size_t(i)] = float(V(i, 0)), ys[size_t(i)] = float(V(i, 1)),
      zs[size_t(i)] = float(V(i, 2));
    if (ordered) {
      const std::vector<int> ord = ks::morton_order(V);
      for (int k = 0; k < n; ++k) {
        const long i = ord[size_t(k)];
        xs[size_t(k)] = float(V(i, 0)), ys[size_t(k)] = float(V(i, 1)),
        zs[size_t(k)] = float(V(i, 2));
      }
    }
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> U(-1.f, 1.f);
    feats.resize(size_t(n) * size_t(tp.feature_dim()));
    dfeats.resize(feats.size());
    for (auto& d : dfeats) d = U(rng);
    dplanes.assign(tp.size(), 0.f);
  }
};

// The lookup loops: 0 = the portable ones, 1 = the AVX2+FMA ones where the CPU has them (as a
// fit runs; triplane_kernels.hpp).
struct TriplanePath {
  explicit TriplanePath(int64_t avx2) {
    ks::triplane_kernels::set_path(avx2 ? ks::triplane_kernels::Path::kAuto
                                        : ks::triplane_kernels::Path::kPortable);
  }
  ~TriplanePath() { ks::triplane_kernels::set_path(ks::triplane_kernels::Path::kAuto); }
};

// Args: ordered, threads, avx2.
void BM_TriplaneForward(benchmark::State& st) {
  TriplaneFixture f(st.range(0) != 0);
  const TriplanePath path(st.range(2));
  const int n = f.n;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(1)));
  for (auto _ : st) {
    ks::triplane_forward(f.tp, f.xs.data(), f.ys.data(), f.zs.data(), n, f.feats.data());
    benchmark::DoNotOptimize(f.feats.data());
  }
  omp_set_num_threads(saved);
}

// Zero the plane gradient, then accumulate, with the points' bins made once outside the loop (as
// the decoder does for its fixed anchors). Args: ordered, threads, avx2.
void BM_TriplaneBackward(benchmark::State& st) {
  TriplaneFixture f(st.range(0) != 0);
  const TriplanePath path(st.range(2));
  const int n = f.n;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(1)));
  const ks::TriplaneBins bins = ks::triplane_bins(f.tp, f.xs.data(), f.ys.data(), f.zs.data(), n);
  for (auto _ : st) {
    f.dplanes.assign(f.tp.size(), 0.f);
    ks::triplane_backward(f.tp, f.xs.data(), f.ys.data(), f.zs.data(), n, f.dfeats.data(),
                          f.dplanes.data(), &bins);
    benchmark::DoNotOptimize(f.dplanes.data());
  }
  omp_set_num_threads(saved);
}

// The decoder's share of a training step at the CLI defaults (DecoderOptions{}: a 512 x 512 x 32
// triplane, two 32-wide MLPs) on the 2-level template in the trainer's order: decode, then the
// backward from fixed random gradients of the Gaussians. Args: threads, texel (0: the MLPs' first
// layers point by point on the triplane's features; 1: in texel space where the CPU has AVX2, as a
// fit runs: reconstruct/texel_layer0.hpp).
void BM_DecoderStep(benchmark::State& st) {
  const ks::BodyModel& body = ks::default_body_model();
  const ks::Subdivision sub = ks::subdivide(ks::TriMesh{body.v_template, body.faces}, 2);
  const Eigen::MatrixXd& V = sub.mesh.V;
  const int n = int(V.rows());
  const std::vector<int> ord = ks::morton_order(V);
  Eigen::MatrixXd anchors(n, 3);
  const size_t count = static_cast<size_t>(n);
  std::vector<float> xs(count), ys(count), zs(count), bias(count, 0.f);
  for (int k = 0; k < n; ++k) {
    anchors.row(k) = V.row(ord[size_t(k)]);
    xs[size_t(k)] = float(anchors(k, 0)), ys[size_t(k)] = float(anchors(k, 1));
    zs[size_t(k)] = float(anchors(k, 2));
  }
  ks::TexelLayer0::set_path(st.range(1) ? ks::TexelLayer0::Path::kAuto
                                        : ks::TexelLayer0::Path::kPoints);
  const float sh0[3] = {0.5f, 0.5f, 0.5f};
  ks::Decoder d;
  d.init(ks::DecoderOptions{}, 1, V, sub.mesh.F, 0.f, sh0);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> U(-1e-3f, 1e-3f);
  std::vector<float> d3(3 * size_t(n)), d3b(d3.size()), d3c(d3.size()), d3d(d3.size()),
      d4(4 * count), d1(count);
  for (auto* v : {&d3, &d3b, &d3c, &d3d, &d4, &d1})
    for (float& x : *v) x = U(rng);
  ks::Gaussians g;
  std::vector<float> offsets;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(0)));
  // The first step also makes what depends on the points only (bins, taps), as a fit's first does.
  d.decode(anchors, xs, ys, zs, bias, g, offsets);
  d.backward(xs, ys, zs, d3, d3b, d3c, d4, d1, d3d);
  for (auto _ : st) {
    d.decode(anchors, xs, ys, zs, bias, g, offsets);
    d.backward(xs, ys, zs, d3, d3b, d3c, d4, d1, d3d);
    benchmark::DoNotOptimize(g.means.data());
  }
  omp_set_num_threads(saved);
  ks::TexelLayer0::set_path(ks::TexelLayer0::Path::kAuto);
}

// The SSIM term of a training step at 512x768 RGB: render against frame, value and gradient.
// Args: the share of the picture (percent of width and of height, centred) where the two images
// differ (a person's box in a training frame is about 40-60 % of the area, or 100 when a frame's
// background is noisy), threads.
void BM_SsimLoss(benchmark::State& st) {
  const int w = 512, h = 768, ch = 3;
  const double share = double(st.range(0)) / 100.0;
  const int bw = int(w * share), bh = int(h * share), bx = (w - bw) / 2, by = (h - bh) / 2;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(0.f, 1.f);
  std::vector<float> x(size_t(w) * h * ch, 0.25f), y(x.size(), 0.25f), dx(x.size());
  for (int yy = by; yy < by + bh; ++yy)
    for (int xx = bx; xx < bx + bw; ++xx)
      for (int k = 0; k < ch; ++k) {
        const size_t i = (size_t(yy) * w + xx) * ch + k;
        y[i] = U(rng);
        x[i] = 0.8f * y[i] + 0.2f * U(rng);
      }
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(1)));
  for (auto _ : st) {
    benchmark::DoNotOptimize(
        ks::ssim<float>(x.data(), y.data(), w, h, ch, nullptr, -0.2f, dx.data()));
  }
  omp_set_num_threads(saved);
}

// One Laplacian term of a training step (the trainer has two: anchor offsets and colours), value
// and gradient, on the default body's template subdivided twice with its part labels carried.
// Args: threads.
void BM_LaplacianLoss(benchmark::State& st) {
  const ks::BodyModel& body = ks::default_body_model();
  const ks::Subdivision sub = ks::subdivide(ks::TriMesh{body.v_template, body.faces}, 2);
  const int n = int(sub.mesh.V.rows());
  const ks::Laplacian lap = ks::build_laplacian(
      ks::vertex_adjacency(sub.mesh.F, n), ks::carry_labels(sub.S, body.part_labels),
      ks::LaplacianMode::kSemantic, ks::default_part_strengths());
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  std::vector<float> a(3 * size_t(n)), da(a.size(), 0.f);
  for (auto& x : a) x = 0.01f * U(rng);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(0)));
  for (auto _ : st)
    benchmark::DoNotOptimize(ks::laplacian_loss<float>(lap, a.data(), 3, 0.1f, da.data()));
  omp_set_num_threads(saved);
  st.counters["vertices"] = n;
}

}  // namespace

BENCHMARK(BM_LaplacianLoss)
    ->ArgsProduct({{1, 2}})
    ->ArgNames({"threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_SsimLoss)
    ->ArgsProduct({{100, 70}, {1, 2}})
    ->ArgNames({"share", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_AdamStep)
    ->ArgsProduct({{3 * 512 * 512 * 32}, {1, 2}})
    ->ArgNames({"params", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_TriplaneForward)
    ->ArgsProduct({{0, 1}, {1, 2}, {0, 1}})
    ->ArgNames({"ordered", "threads", "avx2"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_TriplaneBackward)
    ->ArgsProduct({{0, 1}, {1, 2}, {0, 1}})
    ->ArgNames({"ordered", "threads", "avx2"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DecoderStep)
    ->ArgsProduct({{1, 2}, {0, 1}})
    ->ArgNames({"threads", "texel"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_MAIN();
