// Google Benchmark: the avatar decoders (96 -> H -> H -> 9 geometry, 96 -> H -> H -> 3
// appearance; H = 32, the CLI default, or 64) at the trainer's point counts (template with 1 and 2
// Loop levels), forward and forward + backward (with dL/dX, as the trainer calls it), on 1 and 2
// OpenMP threads; and the decoder's two heads on one input as the trainer runs them, one after the
// other or as a pair (mlp_forward_pair / mlp_backward_pair).
// KS_MLP_NO_AVX2=1 selects the Eigen path; KS_MLP_NO_AVX512=1 the AVX2 kernels on an AVX-512 CPU.
#include <benchmark/benchmark.h>
#include <omp.h>

#include <random>

#include "reconstruct/mlp.hpp"

namespace {

struct Fixture {
  ks::Mlp m;
  ks::MlpCache cache;
  ks::MlpGrads g;
  ks::Mlp::Mat X, Y, dY, dX;
  Fixture(int out, int n, int hidden) {
    m.init({96, hidden, hidden, out}, 5, 0.5f);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> U(-1.f, 1.f);
    X.resize(96, n);
    dY.resize(out, n);
    for (int i = 0; i < X.size(); ++i) X.data()[i] = U(rng);
    for (int i = 0; i < dY.size(); ++i) dY.data()[i] = U(rng);
    g.zero_like(m);
  }
};

// Args: outputs (9 geometry, 3 appearance), points, threads, hidden width.
void BM_Forward(benchmark::State& st) {
  Fixture f(int(st.range(0)), int(st.range(1)), int(st.range(3)));
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(2)));
  ks::mlp_forward(f.m, f.X, f.cache, f.Y);
  for (auto _ : st) {
    ks::mlp_forward(f.m, f.X, f.cache, f.Y);
    benchmark::DoNotOptimize(f.Y.data());
  }
  omp_set_num_threads(saved);
  st.counters["points/s"] = benchmark::Counter(double(st.iterations()) * double(st.range(1)),
                                               benchmark::Counter::kIsRate);
}

void BM_ForwardBackward(benchmark::State& st) {
  Fixture f(int(st.range(0)), int(st.range(1)), int(st.range(3)));
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(2)));
  ks::mlp_forward(f.m, f.X, f.cache, f.Y);
  ks::mlp_backward(f.m, f.cache, f.dY, f.g, &f.dX);
  for (auto _ : st) {
    f.g.zero_like(f.m);
    ks::mlp_forward(f.m, f.X, f.cache, f.Y);
    ks::mlp_backward(f.m, f.cache, f.dY, f.g, &f.dX);
    benchmark::DoNotOptimize(f.dX.data());
  }
  omp_set_num_threads(saved);
  st.counters["points/s"] = benchmark::Counter(double(st.iterations()) * double(st.range(1)),
                                               benchmark::Counter::kIsRate);
}

// Both heads (32 wide) on one input, forward and backward with the summed input gradient, the
// input not kept (the decoder's calls). Args: points, threads, pair (0: one MLP after the other,
// 1: mlp_forward_pair / mlp_backward_pair).
void BM_Heads(benchmark::State& st) {
  const int n = int(st.range(0));
  Fixture geo(9, n, 32), app(3, n, 32);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(int(st.range(1)));
  const bool pair = st.range(2) != 0;
  const ks::Mlp::Mat& X = geo.X;
  for (auto _ : st) {
    geo.g.zero_like(geo.m);
    app.g.zero_like(app.m);
    if (pair) {
      ks::mlp_forward_pair(geo.m, app.m, X, geo.cache, geo.Y, app.cache, app.Y);
      ks::mlp_backward_pair(geo.m, geo.cache, geo.dY, geo.g, app.m, app.cache, app.dY, app.g,
                            geo.dX, X.data());
    } else {
      ks::mlp_forward(geo.m, X, geo.cache, geo.Y, false);
      ks::mlp_forward(app.m, X, app.cache, app.Y, false);
      ks::mlp_backward(geo.m, geo.cache, geo.dY, geo.g, &geo.dX, X.data());
      ks::mlp_backward(app.m, app.cache, app.dY, app.g, &geo.dX, X.data(), true);
    }
    benchmark::DoNotOptimize(geo.dX.data());
  }
  omp_set_num_threads(saved);
}

void Args(benchmark::internal::Benchmark* b) {
  for (int hidden : {32, 64})
    for (int threads : {1, 2})
      for (int n : {41346, 165378})
        for (int out : {9, 3}) b->Args({out, n, threads, hidden});
  b->ArgNames({"out", "n", "threads", "hidden"});
}

}  // namespace

BENCHMARK(BM_Forward)->Apply(Args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ForwardBackward)->Apply(Args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Heads)
    ->ArgsProduct({{165378}, {1, 2}, {0, 1}})
    ->ArgNames({"n", "threads", "pair"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_MAIN();
