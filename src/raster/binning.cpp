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

// Stable radix sort of (key, id) pairs by key, all keys in [lo, hi], in two stages: by the top 8
// bits of key - lo first (256 buckets: each thread's write streams fit the core's first-level
// cache, and Gaussians that lie near each other in id order, as an avatar's do, land in the same
// few buckets), then each bucket by its remaining bits in LSD passes of at most 8 bits within the
// bucket (a few thousand keys, which stay in cache), the buckets shared among the threads in
// contiguous runs of about equal size. Ties keep their order. Only `ids` comes back sorted: the
// last pass does not move the keys (nothing reads them after the sort). (Until the twenty-sixth
// session: LSD passes of up to 12 bits over all the keys, docs/rasterizer.md.)
void radix_sort(std::vector<uint32_t>& keys, std::vector<uint32_t>& ids,
                std::vector<uint32_t>& keys2, std::vector<uint32_t>& ids2,
                std::vector<uint32_t>& hist, uint32_t lo, uint32_t hi) {
  const int span_bits = hi > lo ? 32 - __builtin_clz(hi - lo) : 0;
  constexpr int kTop = 8, kBuckets = 1 << kTop;
  // The bits below the top stage's, in passes of at most 8 (none when the span fits 8 bits).
  const int shift = std::max(span_bits - kTop, 0);
  const int passes = (shift + 7) / 8, bits = passes > 0 ? (shift + passes - 1) / passes : 0;
  const uint32_t mask = (1u << bits) - 1;
  const size_t n = keys.size();
  keys2.resize(n);
  ids2.resize(n);
  const int maxthreads = n > 20000 ? omp_get_max_threads() : 1;
  hist.resize(size_t(maxthreads) * kBuckets + kBuckets + 1);
  uint32_t* start = &hist[size_t(maxthreads) * kBuckets];  // bucket d: [start[d], start[d + 1])
  // The local passes go keys2 -> keys -> keys2 ...: the ids end in `fin`.
  std::vector<uint32_t>& fin = passes % 2 ? ids : ids2;
#pragma omp parallel num_threads(maxthreads)
  {
    const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
    const size_t b = n * tid / nt, e = n * (tid + 1) / nt;
    uint32_t* h = &hist[size_t(tid) * kBuckets];
    std::fill(h, h + kBuckets, 0u);
    for (size_t i = b; i < e; ++i) ++h[(keys[i] - lo) >> shift];
#pragma omp barrier
#pragma omp single
    {
      uint32_t sum = 0;
      for (int d = 0; d < kBuckets; ++d) {
        start[d] = sum;
        for (int t = 0; t < nt; ++t) {
          uint32_t& c = hist[size_t(t) * kBuckets + d];
          const uint32_t tmp = c;
          c = sum;
          sum += tmp;
        }
      }
      start[kBuckets] = sum;
    }
    for (size_t i = b; i < e; ++i) {
      const uint32_t d = h[(keys[i] - lo) >> shift]++;
      keys2[d] = keys[i];
      ids2[d] = ids[i];
    }
#pragma omp barrier
    // This thread's run of buckets: those that start in its share of the keys.
    int d0 = 0, d1 = 0;
    {
      const uint32_t s0 = uint32_t(n * tid / nt), s1 = uint32_t(n * (tid + 1) / nt);
      while (d0 < kBuckets && start[d0] < s0) ++d0;
      d1 = d0;
      while (d1 < kBuckets && start[d1] < s1) ++d1;
      if (tid == nt - 1) d1 = kBuckets;
    }
    uint32_t lh[256];
    for (int d = d0; d < d1; ++d) {
      const uint32_t s = start[d], t = start[d + 1];
      if (t - s <= 1) {
        if (t > s) fin[s] = ids2[s];
        continue;
      }
      for (int pass = 0; pass < passes; ++pass) {
        const int sh = pass * bits;
        const bool from2 = pass % 2 == 0;  // keys2 -> keys on the first pass
        const uint32_t* ks = from2 ? keys2.data() : keys.data();
        const uint32_t* is = from2 ? ids2.data() : ids.data();
        uint32_t* kd = from2 ? keys.data() : keys2.data();
        uint32_t* id = from2 ? ids.data() : ids2.data();
        std::fill(lh, lh + (1 << bits), 0u);
        for (uint32_t i = s; i < t; ++i) ++lh[((ks[i] - lo) >> sh) & mask];
        uint32_t sum = s;
        for (int k = 0; k < (1 << bits); ++k) {
          const uint32_t c = lh[k];
          lh[k] = sum;
          sum += c;
        }
        if (pass + 1 < passes)
          for (uint32_t i = s; i < t; ++i) {
            const uint32_t q = lh[((ks[i] - lo) >> sh) & mask]++;
            kd[q] = ks[i];
            id[q] = is[i];
          }
        else
          for (uint32_t i = s; i < t; ++i) id[lh[((ks[i] - lo) >> sh) & mask]++] = is[i];
      }
    }
  }
  if (&fin == &ids2) ids.swap(ids2);
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
  uint32_t lo = ~uint32_t(0), hi = 0;  // the keys' range
#pragma omp parallel num_threads(nth) reduction(min : lo) reduction(max : hi)
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
        const uint32_t key = depth_key(out.depths[i]);
        lo = std::min(lo, key), hi = std::max(hi, key);
        keys[w] = key;
        ids[w++] = uint32_t(i);
      }
  }
  radix_sort(keys, ids, out.scratch_keys2, out.scratch_ids2, out.scratch_counts, lo, hi);
  const size_t nvis = ids.size();
  timer.mark("sort");

  // The tile lists hold Gaussian ids, and the records stay where the projection wrote them (by
  // id; `records` becomes `packed`, the two buffers swap below): the tile loops gather records
  // through the lists either way, and copying them into depth order first cost a third of this
  // phase, more than it saved the tile loops (docs/rasterizer.md, step 3).
  // Binning, each thread over its contiguous slice of the depth order: its per-tile counts from
  // the tile rectangles the projection wrote (gathered once into depth order), then a prefix sum
  // over (tile, thread) gives every thread its write offsets, and each scatters its slice. Slices
  // are in depth order, so every tile list comes out depth-sorted (stable).
  const int maxthreads = omp_get_max_threads();
  auto& counts = out.scratch_counts;
  counts.resize(size_t(maxthreads) * ntiles);
  const uint32_t* rects = out.tile_rects.data();
  out.scratch_keys2.resize(2 * nvis);  // free after the sort: the rectangles in depth order
  uint32_t* sorted_rects = out.scratch_keys2.data();
#pragma omp parallel
  {
    const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
    const size_t b = nvis * tid / nt, e = nvis * (tid + 1) / nt;
    uint32_t* cnt = &counts[size_t(tid) * ntiles];
    std::fill(cnt, cnt + ntiles, 0u);
    for (size_t k = b; k < e; ++k) {
      const uint32_t id = ids[k];
      if (k + 16 < e) __builtin_prefetch(&rects[2 * size_t(ids[k + 16])]);
      const uint32_t xr = rects[2 * id], yr = rects[2 * id + 1];
      sorted_rects[2 * k] = xr, sorted_rects[2 * k + 1] = yr;
      const auto [tx0, tx1, ty0, ty1] = unpack_tile_rect(xr, yr);
      const int nx = tx1 - tx0, ny = ty1 - ty0, t = ty0 * tiles_x + tx0;
      if ((nx | ny) <= 1) {  // at most 2 x 2 tiles (most Gaussians): no loop to mispredict
        // The four counters (some the same one when nx or ny is 0) read before any is
        // written, then written last-first, so that where two coincide the first tile's
        // write lands last: the counts as four increments in turn, without a chain of
        // stores and reloads through one counter.
        const int dy = ny * tiles_x;
        const uint32_t c0 = cnt[t], c1 = cnt[t + nx], c2 = cnt[t + dy], c3 = cnt[t + nx + dy];
        cnt[t + nx + dy] = c3 + uint32_t(nx & ny);
        cnt[t + dy] = c2 + uint32_t(ny);
        cnt[t + nx] = c1 + uint32_t(nx);
        cnt[t] = c0 + 1;
      } else {
        for (int ty = ty0; ty <= ty1; ++ty)
          for (int tx = tx0; tx <= tx1; ++tx) ++cnt[ty * tiles_x + tx];
      }
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
    uint32_t* list = out.point_list.data();
    for (size_t k = b; k < e; ++k) {
      const uint32_t id = ids[k];
      const auto [tx0, tx1, ty0, ty1] =
          unpack_tile_rect(sorted_rects[2 * k], sorted_rects[2 * k + 1]);
      const int nx = tx1 - tx0, ny = ty1 - ty0, t = ty0 * tiles_x + tx0;
      if ((nx | ny) <= 1) {
        // Four writes, no branch: an absent tile's counter is one of the present ones' (t + nx
        // is t when nx is 0, and so on), so its write repeats one of theirs, the same id into
        // the same slot. The counters read before and written after, last-first, as in the
        // count above.
        const int dy = ny * tiles_x;
        const uint32_t c0 = cnt[t], c1 = cnt[t + nx], c2 = cnt[t + dy], c3 = cnt[t + nx + dy];
        const int nxy = nx & ny;
        list[c0] = id;
        list[c1] = id;
        list[c2] = id;
        list[c3] = id;
        cnt[t + nx + dy] = c3 + uint32_t(nxy);
        cnt[t + dy] = c2 + uint32_t(ny);
        cnt[t + nx] = c1 + uint32_t(nx);
        cnt[t] = c0 + 1;
      } else {
        for (int ty = ty0; ty <= ty1; ++ty)
          for (int tx = tx0; tx <= tx1; ++tx) list[cnt[ty * tiles_x + tx]++] = id;
      }
    }
  }
  out.packed.swap(out.records);
  timer.mark("bin");
}

template void sort_and_bin(RasterResultT<float>&, int, int);
template void sort_and_bin(RasterResultT<double>&, int, int);

}  // namespace ks::raster
