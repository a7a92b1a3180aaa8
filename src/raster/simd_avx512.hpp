#pragma once
// AVX-512 helpers of the rasterizer's AVX-512 tile kernels (inlined into functions compiled for
// AVX-512 only; x86-64).
#if defined(__x86_64__)
#include <immintrin.h>

namespace ks::raster {

// exp for x <= 0: Simd<float, CW>::exp written with AVX-512 operations (same constants, same
// order of operations).
[[gnu::always_inline, gnu::target("avx512f,avx512dq,avx512bw,avx512vl")]] inline __m512 exp16(
    __m512 x) {
  x = _mm512_max_ps(_mm512_set1_ps(-87.0f), x);  // x < -87 ? -87 : x, NaN kept
  const __m512 t = _mm512_mul_ps(x, _mm512_set1_ps(1.4426950408889634f));
  const __m512 k =
      _mm512_sub_ps(_mm512_add_ps(t, _mm512_set1_ps(12582912.0f)), _mm512_set1_ps(12582912.0f));
  const __m512 r =
      _mm512_sub_ps(_mm512_sub_ps(x, _mm512_mul_ps(k, _mm512_set1_ps(0.693145751953125f))),
                    _mm512_mul_ps(k, _mm512_set1_ps(1.428606765330187e-06f)));
  const __m512 r2 = _mm512_mul_ps(r, r), r4 = _mm512_mul_ps(r2, r2);
  const __m512 p01 = _mm512_add_ps(r, _mm512_set1_ps(1.0f));
  const __m512 p23 =
      _mm512_add_ps(_mm512_mul_ps(r, _mm512_set1_ps(1.0f / 6.0f)), _mm512_set1_ps(0.5f));
  const __m512 p45 =
      _mm512_add_ps(_mm512_mul_ps(r, _mm512_set1_ps(1.0f / 120.0f)), _mm512_set1_ps(1.0f / 24.0f));
  const __m512 p = _mm512_add_ps(
      _mm512_add_ps(p01, _mm512_mul_ps(r2, p23)),
      _mm512_mul_ps(r4, _mm512_add_ps(p45, _mm512_mul_ps(r2, _mm512_set1_ps(1.0f / 720.0f)))));
  const __m512i bits =
      _mm512_slli_epi32(_mm512_add_epi32(_mm512_cvtps_epi32(k), _mm512_set1_epi32(127)), 23);
  return _mm512_mul_ps(p, _mm512_castsi512_ps(bits));
}

}  // namespace ks::raster

#endif
