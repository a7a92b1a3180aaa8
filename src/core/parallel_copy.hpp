#pragma once
// Copies, fills and comparisons of large arrays over the threads: the training step's per-step
// copies (decoded Gaussians, unposed attributes, gradient images) ran on one thread while the
// other waited. Small arrays (below kParallelMin elements) stay on the calling thread.
#include <algorithm>
#include <cstddef>
#include <cstring>
#include <type_traits>
#include <vector>

namespace ks {

inline constexpr size_t kParallelMin = size_t(1) << 16;

// dst[0, n) = src[0, n) (the ranges do not overlap).
template <class T>
void parallel_copy(const T* src, size_t n, T* dst) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (n < kParallelMin) {
    if (n) std::memcpy(dst, src, n * sizeof(T));
    return;
  }
  constexpr size_t kChunk = size_t(1) << 15;
  const long chunks = long((n + kChunk - 1) / kChunk);
#pragma omp parallel for schedule(static)
  for (long c = 0; c < chunks; ++c) {
    const size_t b = size_t(c) * kChunk, e = std::min(n, b + kChunk);
    std::memcpy(dst + b, src + b, (e - b) * sizeof(T));
  }
}

// dst = src, as std::vector's assignment leaves it (size and contents).
template <class T>
void parallel_assign(std::vector<T>& dst, const std::vector<T>& src) {
  if (&dst == &src) return;
  dst.resize(src.size());
  parallel_copy(src.data(), src.size(), dst.data());
}

// dst[0, n) = v.
template <class T>
void parallel_fill(T* dst, size_t n, T v) {
  if (n < kParallelMin) {
    std::fill(dst, dst + n, v);
    return;
  }
  constexpr size_t kChunk = size_t(1) << 15;
  const long chunks = long((n + kChunk - 1) / kChunk);
#pragma omp parallel for schedule(static)
  for (long c = 0; c < chunks; ++c) {
    const size_t b = size_t(c) * kChunk, e = std::min(n, b + kChunk);
    std::fill(dst + b, dst + e, v);
  }
}

// a == b, as std::vector's operator== says (sizes equal, then every element ==).
template <class T>
bool parallel_equal(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return false;
  const size_t n = a.size();
  if (n < kParallelMin) return std::equal(a.begin(), a.end(), b.begin());
  constexpr size_t kChunk = size_t(1) << 15;
  const long chunks = long((n + kChunk - 1) / kChunk);
  bool differ = false;
#pragma omp parallel for schedule(static) reduction(|| : differ)
  for (long c = 0; c < chunks; ++c) {
    const size_t b0 = size_t(c) * kChunk, e = std::min(n, b0 + kChunk);
    differ = differ || !std::equal(a.begin() + long(b0), a.begin() + long(e), b.begin() + long(b0));
  }
  return !differ;
}

}  // namespace ks
