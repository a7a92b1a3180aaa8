#pragma once
// Float lanes for code that processes CW items at once with GCC/Clang vector extensions: 4 lanes
// (SSE2, the portable baseline) or 8 (compiled inside a function with the AVX2 target, chosen at
// run time). Only generic vector operations and SSE2 intrinsics are used here, so that the same
// helpers inline into baseline and AVX2 code and give the same results at both widths.
#if defined(__SSE2__)
#include <immintrin.h>
#endif
#include <cstdint>
#include <cstring>

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
  // log(max(x, 1)) plus between 2e-6 and 5e-6 (for x up to 2^24), never below the exact value:
  // a bound that may only grow (the rasterizer's pixel boxes). x = 2^e m with m in [sqrt(1/2),
  // sqrt(2)), log m = 2 atanh(t), t = (m - 1) / (m + 1), |t| < 0.172, by its series to t^9 (the
  // terms left out sum to below 1e-9); the added 4e-6 covers the float rounding. Lane for lane, one
  // vector operation where a loop of std::log calls took eight (NaN lanes give an unspecified
  // value).
  [[gnu::always_inline]] static V log_at_least_one(V x) {
    x = max(x, splat(1.0f));
    const I bits = (I)x;
    I e = (bits >> 23) - 127;
    V m = (V)((bits & 0x7fffff) | 0x3f800000);
    const I big = m > 1.41421356f;
    m = sel(big, m * 0.5f, m);
    e -= big;  // (a true comparison is -1)
    const V t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
    const V p = t * (2.0f + t2 * (2.0f / 3 + t2 * (2.0f / 5 + t2 * (2.0f / 7 + t2 * (2.0f / 9)))));
    return __builtin_convertvector(e, V) * 0.693147182f + p + 4e-6f;
  }
  // Rows to lanes and back by 4 x 4 transposes: a 4-float piece of each of the CW items (a
  // quaternion each, or a third of a 3 x 4 matrix) into four lanes vectors, out[k][l] =
  // rows[l][k], and four lanes vectors into CW 4-float rows. The same values per-lane loops of
  // insertions and extractions give, in a fraction of the instructions.
  typedef float V4 __attribute__((vector_size(16)));
  // CW consecutive floats as lanes (one vector load, not a vector built lane by lane through
  // memory, whose load waits for every lane's store).
  [[gnu::always_inline]] static V load(const float* p) {
    V v;
    std::memcpy(&v, p, sizeof v);
    return v;
  }
  [[gnu::always_inline]] static V4 load4(const float* p) {
    V4 v;
    std::memcpy(&v, p, sizeof v);
    return v;
  }
  [[gnu::always_inline]] static void transpose4(const V4* rows, V* out) {
    V4 t[CW / 4][4];
    for (int g = 0; g < CW / 4; ++g)
      transpose4x4(rows[4 * g], rows[4 * g + 1], rows[4 * g + 2], rows[4 * g + 3], t[g]);
    for (int k = 0; k < 4; ++k) {
      if constexpr (CW == 4)
        out[k] = t[0][k];
      else
        out[k] = __builtin_shufflevector(t[0][k], t[1][k], 0, 1, 2, 3, 4, 5, 6, 7);
    }
  }
  [[gnu::always_inline]] static void untranspose4(const V* in, V4* rows) {
    if constexpr (CW == 4) {
      transpose4x4(in[0], in[1], in[2], in[3], rows);
    } else {
      V4 lo[4], hi[4];
      for (int k = 0; k < 4; ++k) {
        lo[k] = __builtin_shufflevector(in[k], in[k], 0, 1, 2, 3);
        hi[k] = __builtin_shufflevector(in[k], in[k], 4, 5, 6, 7);
      }
      transpose4x4(lo[0], lo[1], lo[2], lo[3], rows);
      transpose4x4(hi[0], hi[1], hi[2], hi[3], rows + 4);
    }
  }
  [[gnu::always_inline]] static void transpose4x4(V4 a, V4 b, V4 c, V4 d, V4* out) {
    const V4 ab0 = __builtin_shufflevector(a, b, 0, 4, 1, 5);
    const V4 ab1 = __builtin_shufflevector(a, b, 2, 6, 3, 7);
    const V4 cd0 = __builtin_shufflevector(c, d, 0, 4, 1, 5);
    const V4 cd1 = __builtin_shufflevector(c, d, 2, 6, 3, 7);
    out[0] = __builtin_shufflevector(ab0, cd0, 0, 1, 4, 5);
    out[1] = __builtin_shufflevector(ab0, cd0, 2, 3, 6, 7);
    out[2] = __builtin_shufflevector(ab1, cd1, 0, 1, 4, 5);
    out[3] = __builtin_shufflevector(ab1, cd1, 2, 3, 6, 7);
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
