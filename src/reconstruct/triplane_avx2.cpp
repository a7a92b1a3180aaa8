// AVX2+FMA loops of the float triplane (see triplane_kernels.hpp): a lookup's four texels are
// blended, or its gradient scattered to them, eight channels a vector. Compiled into the portable
// build with per-function target attributes and chosen at run time.
#include <cstdlib>

#include "reconstruct/mlp_kernels.hpp"
#include "reconstruct/triplane_kernels.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define KS_TRIPLANE_X86 1
#endif

namespace ks::triplane_kernels {

namespace {
Path g_path = Path::kAuto;
}  // namespace

void set_path(Path p) {
  g_path = p;
}

bool use_avx2(int channels) {
  static const bool env_off = [] {
    const char* e = std::getenv("KS_TRIPLANE_NO_AVX2");
    return e != nullptr && e[0] != '\0' && e[0] != '0';
  }();
  if (channels % 8 != 0 || g_path == Path::kPortable || !mlp_kernels::cpu_has_avx2_fma())
    return false;
  return g_path == Path::kAvx2 || !env_off;
}

#if defined(KS_TRIPLANE_X86)

#define KS_AVX2 __attribute__((target("avx2,fma")))

void KS_AVX2 forward_range_avx2(const TriplaneT<float>& tp, const float* xs, const float* ys,
                                const float* zs, int i0, int i1, float* feats) {
  const int C = tp.channels;
  const size_t F = 3 * size_t(C);
  for (int i = i0; i < i1; ++i) {
    float* out = feats + size_t(i) * F;
    for (int p = 0; p < 3; ++p) {
      const Bilinear<float> b = lookup(tp, p, xs[i], ys[i], zs[i]);
      const auto [t00, t10, t01, t11] = texels(tp.planes.data() + p * tp.plane_size(), b, C);
      const __m256 w00 = _mm256_set1_ps(b.w00), w10 = _mm256_set1_ps(b.w10);
      const __m256 w01 = _mm256_set1_ps(b.w01), w11 = _mm256_set1_ps(b.w11);
      float* o = out + p * C;
      for (int c = 0; c < C; c += 8) {
        __m256 acc = _mm256_mul_ps(w00, _mm256_loadu_ps(t00 + c));
        acc = _mm256_fmadd_ps(w10, _mm256_loadu_ps(t10 + c), acc);
        acc = _mm256_fmadd_ps(w01, _mm256_loadu_ps(t01 + c), acc);
        acc = _mm256_fmadd_ps(w11, _mm256_loadu_ps(t11 + c), acc);
        _mm256_storeu_ps(o + c, acc);
      }
    }
  }
}

void KS_AVX2 backward_run_avx2(const TriplaneT<float>& tp, int p, const float* xs, const float* ys,
                               const float* zs, const int* ord, int k0, int k1, const float* dfeats,
                               float* dplane, int ahead) {
  const int C = tp.channels;
  const size_t F = 3 * size_t(C);
  for (int k = k0; k < k1; ++k) {
    const int i = ord[k];
    // The point gradients are read out of order: fetch a later point's ahead of its turn.
    if (k + ahead < k1) {
      const char* a = reinterpret_cast<const char*>(dfeats + size_t(ord[k + ahead]) * F + p * C);
      for (int off = 0; off < int(sizeof(float)) * C; off += 64) _mm_prefetch(a + off, _MM_HINT_T0);
    }
    const Bilinear<float> b = lookup(tp, p, xs[i], ys[i], zs[i]);
    const float* g = dfeats + size_t(i) * F + p * C;
    const auto [t00, t10, t01, t11] = texels(dplane, b, C);
    const __m256 w00 = _mm256_set1_ps(b.w00), w10 = _mm256_set1_ps(b.w10);
    const __m256 w01 = _mm256_set1_ps(b.w01), w11 = _mm256_set1_ps(b.w11);
    for (int c = 0; c < C; c += 8) {
      const __m256 gc = _mm256_loadu_ps(g + c);
      _mm256_storeu_ps(t00 + c, _mm256_fmadd_ps(w00, gc, _mm256_loadu_ps(t00 + c)));
      _mm256_storeu_ps(t10 + c, _mm256_fmadd_ps(w10, gc, _mm256_loadu_ps(t10 + c)));
      _mm256_storeu_ps(t01 + c, _mm256_fmadd_ps(w01, gc, _mm256_loadu_ps(t01 + c)));
      _mm256_storeu_ps(t11 + c, _mm256_fmadd_ps(w11, gc, _mm256_loadu_ps(t11 + c)));
    }
  }
}

#else  // not x86: never selected (use_avx2() is false)

void forward_range_avx2(const TriplaneT<float>&, const float*, const float*, const float*, int, int,
                        float*) {
  std::abort();
}
void backward_run_avx2(const TriplaneT<float>&, int, const float*, const float*, const float*,
                       const int*, int, int, const float*, float*, int) {
  std::abort();
}

#endif

}  // namespace ks::triplane_kernels
