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

// f(b, e) over [0, n) in chunks, over the threads when n >= kParallelMin (else one call); true
// when every call returned true.
template <class F>
bool for_chunks(size_t n, F&& f) {
  if (n < kParallelMin) return f(size_t(0), n);
  constexpr size_t kChunk = size_t(1) << 15;
  const long chunks = long((n + kChunk - 1) / kChunk);
  bool all = true;
#pragma omp parallel for schedule(static) reduction(&& : all)
  for (long c = 0; c < chunks; ++c)
    all = f(size_t(c) * kChunk, std::min(n, size_t(c + 1) * kChunk)) && all;
  return all;
}

// dst[0, n) = src[0, n) (the ranges do not overlap).
template <class T>
void parallel_copy(const T* src, size_t n, T* dst) {
  static_assert(std::is_trivially_copyable_v<T>);
  for_chunks(n, [&](size_t b, size_t e) {
    if (e > b) std::memcpy(dst + b, src + b, (e - b) * sizeof(T));
    return true;
  });
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
  for_chunks(n, [&](size_t b, size_t e) {
    std::fill(dst + b, dst + e, v);
    return true;
  });
}

// a == b, as std::vector's operator== says (sizes equal, then every element ==).
template <class T>
bool parallel_equal(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return false;
  return for_chunks(a.size(), [&](size_t b0, size_t e) {
    return std::equal(a.begin() + long(b0), a.begin() + long(e), b.begin() + long(b0));
  });
}

}  // namespace ks
