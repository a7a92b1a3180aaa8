// The rasterizer's ordering pass: depth order of the visible Gaussians (one global radix sort),
// one packed render record each in that order, and per-tile lists that come out depth-sorted
// without a second sort (docs/rasterizer.md, design steps 2-4).
#include <omp.h>

#include <algorithm>

#include "raster/raster_internal.hpp"

namespace ks::raster {

namespace {

template <class T>
inline uint32_t depth_key(T z) {
  const float f = float(z);
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;  // z > 0: the float bits are monotone in z
}

// Stable LSD radix sort of (key, id) pairs by key: three passes of 11 bits, each over the
// threads (per-thread digit counts, offsets bucket-major then thread so that equal keys keep
// their order, then each thread scatters its own range), a pass whose digit is the same for
// every key skipped. `hist` is scratch.
void radix_sort(std::vector<uint32_t>& keys, std::vector<uint32_t>& ids,
                std::vector<uint32_t>& keys2, std::vector<uint32_t>& ids2,
                std::vector<uint32_t>& hist) {
  constexpr int kBits = 11, kBuckets = 1 << kBits;
  const size_t n = keys.size();
  keys2.resize(n);
  ids2.resize(n);
  const int maxthreads = n > 20000 ? omp_get_max_threads() : 1;
  hist.resize(size_t(maxthreads) * kBuckets);
  for (int shift = 0; shift < 32; shift += kBits) {
    bool trivial = false;
#pragma omp parallel num_threads(maxthreads)
    {
      const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
      const size_t b = n * tid / nt, e = n * (tid + 1) / nt;
      uint32_t* h = &hist[size_t(tid) * kBuckets];
      std::fill(h, h + kBuckets, 0u);
      for (size_t i = b; i < e; ++i) ++h[(keys[i] >> shift) & (kBuckets - 1)];
#pragma omp barrier
#pragma omp single
      {
        uint32_t sum = 0;
        for (int d = 0; d < kBuckets; ++d) {
          uint32_t total = 0;
          for (int t = 0; t < nt; ++t) {
            uint32_t& c = hist[size_t(t) * kBuckets + d];
            const uint32_t tmp = c;
            c = sum;
            sum += tmp;
            total += tmp;
          }
          if (total == n) trivial = true;
        }
      }
      if (!trivial)
        for (size_t i = b; i < e; ++i) {
          const uint32_t d = h[(keys[i] >> shift) & (kBuckets - 1)]++;
          keys2[d] = keys[i];
          ids2[d] = ids[i];
        }
    }
    if (trivial) continue;
    keys.swap(keys2);
    ids.swap(ids2);
  }
}

}  // namespace

template <class T>
void sort_and_bin(RasterResultT<T>& out, int tiles_x, int tiles_y) {
  const size_t N = out.radii.size();
  const int ntiles = tiles_x * tiles_y;
  PhaseTimer timer;
  // Depth order of the visible Gaussians (one global radix sort).
  auto& keys = out.scratch_keys;
  auto& ids = out.scratch_ids;
  // The visible ones in id order: each thread counts its slice, then writes at its offset.
  const int nth = N > 20000 ? omp_get_max_threads() : 1;
  std::vector<size_t> slice_count(size_t(nth) + 1, 0);
#pragma omp parallel num_threads(nth)
  {
    const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
    const size_t b = N * tid / nt, e = N * (tid + 1) / nt;
    size_t c = 0;
    for (size_t i = b; i < e; ++i) c += out.radii[i] > 0;
    slice_count[size_t(tid) + 1] = c;
#pragma omp barrier
#pragma omp single
    {
      for (int t = 0; t < nt; ++t) slice_count[size_t(t) + 1] += slice_count[size_t(t)];
      keys.resize(slice_count[size_t(nt)]);
      ids.resize(slice_count[size_t(nt)]);
    }
    size_t w = slice_count[size_t(tid)];
    for (size_t i = b; i < e; ++i)
      if (out.radii[i] > 0) {
        keys[w] = depth_key(out.depths[i]);
        ids[w++] = uint32_t(i);
      }
  }
  radix_sort(keys, ids, out.scratch_keys2, out.scratch_ids2, out.scratch_counts);
  const size_t nvis = ids.size();
  // Render records in depth order (one 64-byte record for float), so that the tile loops read
  // contiguous records: one record copied per visible Gaussian from those the projection wrote
  // by id (a gather from the eight arrays here took three times as long).
  out.packed.resize(size_t(kRec) * nvis);
#pragma omp parallel for schedule(static)
  for (size_t k = 0; k < nvis; ++k) {
    if (k + 16 < nvis) __builtin_prefetch(&out.records[size_t(kRec) * ids[k + 16]]);
    std::memcpy(&out.packed[size_t(kRec) * k], &out.records[size_t(kRec) * ids[k]],
                kRec * sizeof(T));
  }
  timer.mark("sort");

  // Binning: per thread per tile counts, prefix sum, scatter in depth order (stable).
  const int maxthreads = omp_get_max_threads();
  auto& counts = out.scratch_counts;
  counts.resize(size_t(maxthreads) * ntiles);
#pragma omp parallel
  {
    const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
    const size_t b = nvis * tid / nt, e = nvis * (tid + 1) / nt;
    uint32_t* cnt = &counts[size_t(tid) * ntiles];
    std::fill(cnt, cnt + ntiles, 0u);
    for (size_t k = b; k < e; ++k) {
      const T* r = &out.packed[size_t(kRec) * k + 10];
      const int tx0 = int(r[0]) / kTS, tx1 = int(r[1]) / kTS, ty0 = int(r[2]) / kTS,
                ty1 = int(r[3]) / kTS;
      for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) ++cnt[ty * tiles_x + tx];
    }
#pragma omp barrier
#pragma omp single
    {
      uint32_t off = 0;
      for (int t = 0; t < ntiles; ++t) {
        out.tile_ranges[2 * t] = off;
        for (int th = 0; th < nt; ++th) {
          uint32_t& c = counts[size_t(th) * ntiles + t];
          const uint32_t tmp = c;
          c = off;
          off += tmp;
        }
        out.tile_ranges[2 * t + 1] = off;
      }
      out.point_list.resize(off);
    }
    for (size_t k = b; k < e; ++k) {
      const T* r = &out.packed[size_t(kRec) * k + 10];
      const int tx0 = int(r[0]) / kTS, tx1 = int(r[1]) / kTS, ty0 = int(r[2]) / kTS,
                ty1 = int(r[3]) / kTS;
      for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) out.point_list[cnt[ty * tiles_x + tx]++] = uint32_t(k);
    }
  }
  timer.mark("bin");
}

template void sort_and_bin(RasterResultT<float>&, int, int);
template void sort_and_bin(RasterResultT<double>&, int, int);

}  // namespace ks::raster
