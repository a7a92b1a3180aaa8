#pragma once
// Float lanes for code that processes CW items at once with GCC/Clang vector extensions: 4 lanes
// (SSE2, the portable baseline) or 8 (compiled inside a function with the AVX2 target, chosen at
// run time). Only generic vector operations and SSE2 intrinsics are used here, so that the same
// helpers inline into baseline and AVX2 code and give the same results at both widths.
#if defined(__SSE2__)
#include <immintrin.h>
#endif
#include <cstdint>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

namespace ks {

template <int CW>
struct FloatLanes;

template <>
struct FloatLanes<4> {
  typedef float V __attribute__((vector_size(16)));
  typedef int32_t I __attribute__((vector_size(16)));
};
template <>
struct FloatLanes<8> {
  typedef float V __attribute__((vector_size(32)));
  typedef int32_t I __attribute__((vector_size(32)));
};

template <int CW>
struct Lanes {
  using V = typename FloatLanes<CW>::V;
  using I = typename FloatLanes<CW>::I;
  static constexpr int kWidth = CW;
  [[gnu::always_inline]] static V splat(float x) { return V{} + x; }
  [[gnu::always_inline]] static V sel(I m, V a, V b) { return m ? a : b; }
  [[gnu::always_inline]] static V max(V a, V b) { return a > b ? a : b; }
  [[gnu::always_inline]] static V min(V a, V b) { return a < b ? a : b; }
  // Floor / ceiling for |x| < 2^31 with conversions only (SSE2 has no rounding instruction).
  [[gnu::always_inline]] static V floor(V x) {
    const V t = __builtin_convertvector(__builtin_convertvector(x, I), V);
    return t > x ? t - 1.0f : t;
  }
  [[gnu::always_inline]] static V ceil(V x) {
    const V t = __builtin_convertvector(__builtin_convertvector(x, I), V);
    return t < x ? t + 1.0f : t;
  }
  // sqrtps on 4-lane pieces (SSE, so that it inlines into the baseline and the AVX2 code).
  [[gnu::always_inline]] static V sqrt(V x) {
    if constexpr (CW == 4) {
      return (V)_mm_sqrt_ps((__m128)x);
    } else {
      typedef float V4 __attribute__((vector_size(16)));
      const V4 lo = (V4)_mm_sqrt_ps((__m128)__builtin_shufflevector(x, x, 0, 1, 2, 3));
      const V4 hi = (V4)_mm_sqrt_ps((__m128)__builtin_shufflevector(x, x, 4, 5, 6, 7));
      return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
    }
  }
};

}  // namespace ks

#pragma GCC diagnostic pop
