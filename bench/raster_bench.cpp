// Google Benchmark: rasterizer forward and forward + backward on the avatar-like cloud.
#include <benchmark/benchmark.h>

#include <random>

#include "raster/avatar_cloud.hpp"
#include "raster/rasterizer.hpp"

namespace {

struct Fixture {
  ks::Gaussians g;
  ks::Camera cam;
  ks::RasterResult r;
  ks::RasterGrads gr;
  ks::Image dc, da;
  Fixture(size_t n, int w, int h)
      : g(ks::make_avatar_cloud(n, 1)), cam(ks::avatar_camera(w, h)), dc(w, h, 3), da(w, h, 1) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> U(-1e-3f, 1e-3f);
    for (float& v : dc.data) v = U(rng);
    for (float& v : da.data) v = U(rng);
  }
};

void BM_Forward(benchmark::State& st) {
  Fixture f(size_t(st.range(0)), int(st.range(1)), int(st.range(2)));
  ks::rasterize_forward(f.g, f.cam, {}, f.r);
  for (auto _ : st) {
    ks::rasterize_forward(f.g, f.cam, {}, f.r);
    benchmark::DoNotOptimize(f.r.color.data.data());
  }
  st.counters["fps"] = benchmark::Counter(double(st.iterations()), benchmark::Counter::kIsRate);
}

void BM_ForwardBackward(benchmark::State& st) {
  Fixture f(size_t(st.range(0)), int(st.range(1)), int(st.range(2)));
  ks::rasterize_forward(f.g, f.cam, {}, f.r);
  ks::rasterize_backward(f.g, f.cam, {}, f.r, f.dc, f.da, f.gr);
  for (auto _ : st) {
    ks::rasterize_forward(f.g, f.cam, {}, f.r);
    ks::rasterize_backward(f.g, f.cam, {}, f.r, f.dc, f.da, f.gr);
    benchmark::DoNotOptimize(f.gr.means.data());
  }
}

}  // namespace

BENCHMARK(BM_Forward)
    ->Args({20000, 256, 384})
    ->Args({110000, 512, 768})
    ->Args({110000, 1024, 1536})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_ForwardBackward)
    ->Args({20000, 256, 384})
    ->Args({110000, 512, 768})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_MAIN();
