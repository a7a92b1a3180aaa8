#include "reconstruct/triplane.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <type_traits>
#include <vector>

#include "core/error.hpp"
#include "reconstruct/triplane_kernels.hpp"

namespace ks {

using triplane_kernels::Bilinear;
using triplane_kernels::lookup;

template <typename T>
void TriplaneT<T>::init(int r, int c, const T box_lo[3], const T box_hi[3], uint64_t seed,
                        T init_scale) {
  res = r;
  channels = c;
  for (int k = 0; k < 3; ++k) lo[k] = box_lo[k], hi[k] = box_hi[k];
  planes.assign(size(), T(0));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (auto& p : planes) p = T(u(rng)) * init_scale;
}

template <typename T>
void triplane_forward(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                      T* feats) {
  const int C = tp.channels;
  const int F = 3 * C;
  if constexpr (std::is_same_v<T, float>) {
    if (triplane_kernels::use_avx2(C)) {
      constexpr int kChunk = 2048;
      const int chunks = (n + kChunk - 1) / kChunk;
      // Dynamic: a lookup's cost is its cache misses, which vary along the points.
#pragma omp parallel for schedule(dynamic, 1) if (chunks > 1)
      for (int c = 0; c < chunks; ++c)
        triplane_kernels::forward_range_avx2(tp, xs, ys, zs, c * kChunk,
                                             std::min(n, (c + 1) * kChunk), feats);
      return;
    }
  }
  // Dynamic: a lookup's cost is its cache misses, which vary along the points.
#pragma omp parallel for schedule(dynamic, 2048) if (n > 1024)
  for (int i = 0; i < n; ++i) {
    T* out = feats + size_t(i) * F;
    for (int p = 0; p < 3; ++p) {
      const Bilinear<T> b = lookup(tp, p, xs[i], ys[i], zs[i]);
      const auto [t00, t10, t01, t11] =
          triplane_kernels::texels(tp.planes.data() + p * tp.plane_size(), b, C);
      T* o = out + p * C;
      for (int c = 0; c < C; ++c)
        o[c] = b.w00 * t00[c] + b.w10 * t10[c] + b.w01 * t01[c] + b.w11 * t11[c];
    }
  }
}

template <typename T>
TriplaneBins triplane_bins(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n) {
  const int res = tp.res;
  TriplaneBins B;
  B.n = n, B.res = res;
  B.stripes = std::max(1, std::min(64, (res - 1) / 2));
  const int rows_per = (res - 1 + B.stripes - 1) / B.stripes;  // v0 is in [0, res - 2]
  B.start.assign(size_t(3) * (B.stripes + 1), 0);
  B.order.resize(size_t(3) * n);
  std::vector<int> stripe_of(size_t(3) * n);
#pragma omp parallel for schedule(static) if (n > 1024)
  for (int i = 0; i < n; ++i)
    for (int p = 0; p < 3; ++p)
      stripe_of[size_t(p) * n + i] = (lookup(tp, p, xs[i], ys[i], zs[i]).i00 / res) / rows_per;
  // A stable counting sort of each plane's points by stripe.
  for (int p = 0; p < 3; ++p) {
    int* st = B.start.data() + size_t(p) * (B.stripes + 1);
    const int* so = stripe_of.data() + size_t(p) * n;
    for (int i = 0; i < n; ++i) ++st[so[i] + 1];
    for (int s = 0; s < B.stripes; ++s) st[s + 1] += st[s];
    std::vector<int> fill(st, st + B.stripes);
    int* ord = B.order.data() + size_t(p) * n;
    for (int i = 0; i < n; ++i) ord[fill[size_t(so[i])]++] = i;
  }
  return B;
}

template <typename T>
void triplane_backward(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                       const T* dfeats, T* dplanes, const TriplaneBins* bins) {
  const int C = tp.channels;
  const int F = 3 * C;
  TriplaneBins local;
  if (!bins) {
    local = triplane_bins(tp, xs, ys, zs, n);
    bins = &local;
  }
  if (bins->n != n || bins->res != tp.res)
    throw Error("triplane_backward: the bins are of other points or another plane size");
  const int stripes = bins->stripes;
  constexpr int kAhead = 8;
  const bool avx2 = std::is_same_v<T, float> && triplane_kernels::use_avx2(C);
  for (int parity = 0; parity < 2; ++parity) {
    const int per_plane = (stripes + 1 - parity) / 2;
#pragma omp parallel for schedule(dynamic, 1) if (n > 1024)
    for (int task = 0; task < 3 * per_plane; ++task) {
      const int p = task / per_plane;
      const int s = 2 * (task % per_plane) + parity;
      const int* st = bins->start.data() + size_t(p) * (stripes + 1);
      const int* ord = bins->order.data() + size_t(p) * n;
      T* base = dplanes + p * tp.plane_size();
      const int end = st[s + 1];
      if constexpr (std::is_same_v<T, float>) {
        if (avx2) {
          triplane_kernels::backward_run_avx2(tp, p, xs, ys, zs, ord, st[s], end, dfeats, base,
                                              kAhead);
          continue;
        }
      }
      for (int k = st[s]; k < end; ++k) {
        const int i = ord[k];
        // The point gradients are read out of order: fetch a later point's ahead of its turn.
        if (k + kAhead < end) {
          const char* ahead =
              reinterpret_cast<const char*>(dfeats + size_t(ord[k + kAhead]) * F + p * C);
          for (int off = 0; off < int(sizeof(T)) * C; off += 64) __builtin_prefetch(ahead + off);
        }
        const Bilinear<T> b = lookup(tp, p, xs[i], ys[i], zs[i]);
        const T* g = dfeats + size_t(i) * F + p * C;
        const auto [t00, t10, t01, t11] = triplane_kernels::texels(base, b, C);
        for (int c = 0; c < C; ++c) {
          const T gc = g[c];
          t00[c] += b.w00 * gc;
          t10[c] += b.w10 * gc;
          t01[c] += b.w01 * gc;
          t11[c] += b.w11 * gc;
        }
      }
    }
  }
}

template <typename T>
void triplane_mark_texels(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                          std::vector<uint8_t>* texels) {
  const size_t per_plane = size_t(tp.res) * tp.res;
  if (texels->size() < 3 * per_plane) texels->resize(3 * per_plane, 0);
  uint8_t* t = texels->data();
  for (int i = 0; i < n; ++i)
    for (int p = 0; p < 3; ++p) {
      const Bilinear<T> b = lookup(tp, p, xs[i], ys[i], zs[i]);
      uint8_t* base = t + p * per_plane + b.i00;
      base[0] = base[b.du] = base[b.dv] = base[b.dv + b.du] = 1;
    }
}

std::vector<std::pair<size_t, size_t>> texel_ranges(const std::vector<uint8_t>& texels,
                                                    int channels) {
  std::vector<std::pair<size_t, size_t>> out;
  const size_t C = size_t(channels);
  for (size_t i = 0; i < texels.size();) {
    if (!texels[i]) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j < texels.size() && texels[j]) ++j;
    out.emplace_back(i * C, j * C);
    i = j;
  }
  return out;
}

template struct TriplaneT<float>;
template struct TriplaneT<double>;
template void triplane_forward(const TriplaneT<float>&, const float*, const float*, const float*,
                               int, float*);
template void triplane_forward(const TriplaneT<double>&, const double*, const double*,
                               const double*, int, double*);
template TriplaneBins triplane_bins(const TriplaneT<float>&, const float*, const float*,
                                    const float*, int);
template TriplaneBins triplane_bins(const TriplaneT<double>&, const double*, const double*,
                                    const double*, int);
template void triplane_backward(const TriplaneT<float>&, const float*, const float*, const float*,
                                int, const float*, float*, const TriplaneBins*);
template void triplane_backward(const TriplaneT<double>&, const double*, const double*,
                                const double*, int, const double*, double*, const TriplaneBins*);
template void triplane_mark_texels(const TriplaneT<float>&, const float*, const float*,
                                   const float*, int, std::vector<uint8_t>*);
template void triplane_mark_texels(const TriplaneT<double>&, const double*, const double*,
                                   const double*, int, std::vector<uint8_t>*);

}  // namespace ks
