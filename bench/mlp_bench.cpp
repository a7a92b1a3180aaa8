// Google Benchmark: the avatar decoders (96 -> H -> H -> 9 geometry, 96 -> H -> H -> 3
// appearance; H = 32, the CLI default, or 64) at the trainer's point counts (template with 1 and 2
// Loop levels), forward and forward + backward (with dL/dX, as the trainer calls it), on 1 and 2
// OpenMP threads.
// KS_MLP_NO_AVX2=1 selects the Eigen path.
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
BENCHMARK_MAIN();
