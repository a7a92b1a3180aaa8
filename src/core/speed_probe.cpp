// A fixed arithmetic load on every thread, timed (speed_probe.hpp).
#include "core/speed_probe.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <utility>
#include <vector>

#include "core/math.hpp"

namespace ks {

namespace {

typedef float F4 __attribute__((vector_size(16)));
constexpr int kChains = 12;  // independent chains: enough to keep the units busy (throughput bound)

// Chain k starts at 1 + k / 1024 and takes x <- x * m + c each step (both constants keep it near
// its fixed point c / (1 - m), far from overflow and denormals). Returns the lanes' sum.
float chain_sum(int64_t iterations) {
  F4 a[kChains];
  for (int k = 0; k < kChains; ++k) a[k] = F4{} + (1.0f + float(k) / 1024.0f);
  const F4 m = F4{} + 0.9999f, c = F4{} + 1e-4f;
  for (int64_t i = 0; i < iterations; ++i)
    for (int k = 0; k < kChains; ++k) {
      a[k] = a[k] * m;
      a[k] = a[k] + c;
      // Keeps every chain in registers and every step in the loop (no closed form to find).
#if defined(__x86_64__) || defined(__i386__)
      __asm__ volatile("" : "+x"(a[k]));
#elif defined(__aarch64__)
      __asm__ volatile("" : "+w"(a[k]));
#else
      __asm__ volatile("" : "+m"(a[k]));
#endif
    }
  float s = 0;
  for (int k = 0; k < kChains; ++k) s += a[k][0];
  return s;
}

}  // namespace

double speed_probe_reference(int64_t iterations) {
  float s = 0;
  for (int k = 0; k < kChains; ++k) {
    float x = 1.0f + float(k) / 1024.0f;
    for (int64_t i = 0; i < iterations; ++i) {
      x = x * 0.9999f;
      x = x + 1e-4f;
    }
    s += x;
  }
  return s;
}

SpeedProbe speed_probe(int64_t iterations, int reps) {
  SpeedProbe p;
  std::vector<double> times;
  for (int r = 0; r < std::max(reps, 1); ++r) {
    double sum = 0;
    int threads = 0;
    const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel reduction(+ : sum)
    {
      sum += double(chain_sum(iterations));
#pragma omp single nowait
      threads = omp_get_num_threads();
    }
    times.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    p.checksum = sum;
    p.threads = threads;
  }
  p.ms = median(std::move(times));
  return p;
}

}  // namespace ks
