// The rasterizer's backward tile pass (3DGS's render in backward.cu): every tile in reverse
// depth order from the forward's final transmittance and last contributor per pixel, the
// per-Gaussian screen-space gradients (mean2d, conic, opacity, rgb) reduced over the chunk
// lanes into per-thread accumulators; baseline, AVX2 and AVX-512VL kernels side by side.
#pragma GCC diagnostic ignored "-Wpsabi"
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <type_traits>

#include "raster/raster_internal.hpp"

namespace ks::raster {

namespace {

// acc[0..8] += the lane sums of s[0..8]. For float the nine sums come out of a shuffle tree
// (pairwise sums of neighbouring lanes, three levels for 8 lanes, two for 4) and are added with
// one vector load and store, instead of 9 x CW lane extracts.
template <int CW, class T, class V>
[[gnu::always_inline]] inline void add_lane_sums(const V* s, T* acc) {
  if constexpr (std::is_same_v<T, float> && (CW == 8 || CW == 4)) {
    const auto pair = [](V x, V y) -> V {
      if constexpr (CW == 8)
        return __builtin_shufflevector(x, y, 0, 2, 4, 6, 8, 10, 12, 14) +
               __builtin_shufflevector(x, y, 1, 3, 5, 7, 9, 11, 13, 15);
      else
        return __builtin_shufflevector(x, y, 0, 2, 4, 6) +
               __builtin_shufflevector(x, y, 1, 3, 5, 7);
    };
    V sums[8 / CW];
    if constexpr (CW == 8) {
      sums[0] =
          pair(pair(pair(s[0], s[1]), pair(s[2], s[3])), pair(pair(s[4], s[5]), pair(s[6], s[7])));
    } else {
      sums[0] = pair(pair(s[0], s[1]), pair(s[2], s[3]));
      sums[1] = pair(pair(s[4], s[5]), pair(s[6], s[7]));
    }
    for (int h = 0; h < 8 / CW; ++h) {
      V a;
      std::memcpy(&a, acc + h * CW, sizeof(V));
      a += sums[h];
      std::memcpy(acc + h * CW, &a, sizeof(V));
    }
    V x = s[8];
    if constexpr (CW == 8) {
      x += __builtin_shufflevector(x, x, 4, 5, 6, 7, 0, 1, 2, 3);
      x += __builtin_shufflevector(x, x, 2, 3, 0, 1, 2, 3, 0, 1);
    } else {
      x += __builtin_shufflevector(x, x, 2, 3, 0, 1);
    }
    acc[8] += x[0] + x[1];
  } else {
    for (int l = 0; l < CW; ++l)
      for (int q = 0; q < kNG; ++q) acc[q] += s[q][l];
  }
}

// One tile of the backward pass (reverse order), accumulating into `acc` (9 per Gaussian). One
// SIMD vector is a block of BW x BH pixels, the forward's layout (block_index).
template <int BW, int BH, class T, class Res, class Img>
[[gnu::always_inline]] inline void backward_tile(const Res& fwd, const Img& dLdc, const Img& dLda,
                                                 bool has_da, const T* bg, T* acc, int tile,
                                                 int tiles_x, int W, int H) {
  constexpr int N = BW * BH, kBlocks = kTilePixels / N;
  const uint32_t start = fwd.tile_ranges[2 * tile], end = fwd.tile_ranges[2 * tile + 1];
  if (start == end) return;
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  // DT: dL/dalpha times the final transmittance (the one place either is read).
  alignas(64) T Tt[kTilePixels], R0[kTilePixels], R1[kTilePixels], R2[kTilePixels], D0[kTilePixels],
      D1[kTilePixels], D2[kTilePixels], DT[kTilePixels];
  using SV = Simd<T, N>;
  using V = typename SV::V;
  using VI = typename SV::I;
  using SI = typename SV::S;
  alignas(64) SI last[kTilePixels];
  int jmax = 0;  // one past the tile's last contributor
  // Four pixels of a row at a time where the image holds them (dL/dcolor de-interleaved by
  // shuffles), the rest one at a time; the same values either way.
  static_assert(fours_side_by_side<block_index<BW, BH>>(), "rows of four pixels side by side");
  using Data = std::remove_cv_t<std::remove_reference_t<decltype(dLdc.data[0])>>;
  constexpr bool kByFours = std::is_same_v<Data, T> && sizeof(SI) == 4;  // (float)
  typedef T V4 __attribute__((vector_size(4 * sizeof(T))));
  typedef SI I4 __attribute__((vector_size(4 * sizeof(SI))));
  I4 jmax4{};
  const int w4 = kByFours ? std::min(kTS, W - ox) & ~3 : 0;
  for (int r = 0; r < kTS && oy + r < H; ++r)
    for (int c = 0; c < w4; c += 4) {
      const int p = block_index<BW, BH>(c, r);
      const size_t pix = size_t(oy + r) * W + ox + size_t(c);
      const V4 ft = vload<V4>(&fwd.final_T[pix]);
      vstore(Tt + p, ft);
      I4 lc;
      std::memcpy(&lc, &fwd.n_contrib[pix], sizeof lc);  // (counts below 2^31)
      vstore(last + p, lc);
      jmax4 = jmax4 > lc ? jmax4 : lc;
      const T* d = &dLdc.data[3 * pix];
      const V4 a = vload<V4>(d), b = vload<V4>(d + 4), e = vload<V4>(d + 8);
      const V4 t0 = __builtin_shufflevector(a, b, 0, 3, 6, 7);
      const V4 t1 = __builtin_shufflevector(a, b, 1, 4, 7, 7);
      const V4 t2 = __builtin_shufflevector(a, b, 2, 5, 5, 5);
      vstore(D0 + p, __builtin_shufflevector(t0, e, 0, 1, 2, 5));
      vstore(D1 + p, __builtin_shufflevector(t1, e, 0, 1, 2, 6));
      vstore(D2 + p, __builtin_shufflevector(t2, e, 0, 1, 4, 7));
      vstore(DT + p, has_da ? vload<V4>(&dLda.data[pix]) * ft : V4{});
      vstore(R0 + p, V4{} + bg[0]), vstore(R1 + p, V4{} + bg[1]), vstore(R2 + p, V4{} + bg[2]);
    }
  for (int l = 0; l < 4; ++l) jmax = std::max(jmax, int(jmax4[l]));
  for (int r = 0; r < kTS; ++r)
    for (int c = oy + r < H ? w4 : 0; c < kTS; ++c) {
      const int p = block_index<BW, BH>(c, r);
      if (ox + c < W && oy + r < H) {
        const size_t pix = size_t(oy + r) * W + ox + c;
        Tt[p] = fwd.final_T[pix];
        last[p] = SI(fwd.n_contrib[pix]);
        D0[p] = T(dLdc.data[3 * pix]), D1[p] = T(dLdc.data[3 * pix + 1]),
        D2[p] = T(dLdc.data[3 * pix + 2]);
        DT[p] = has_da ? T(dLda.data[pix]) * Tt[p] : T(0);
      } else {
        Tt[p] = 1, last[p] = 0, D0[p] = D1[p] = D2[p] = DT[p] = 0;
      }
      R0[p] = bg[0], R1[p] = bg[1], R2[p] = bg[2];
      jmax = std::max(jmax, int(last[p]));
    }
  const V col_off = block_columns<V, BW, BH>(), row_off = block_rows<V, BW, BH>();
  alignas(64) V lane_cols[kBlocks], lane_rows[kBlocks];
  for (int blk = 0; blk < kBlocks; ++blk)
    block_lanes<BW, BH>(blk, col_off, row_off, lane_cols[blk], lane_rows[blk]);
  alignas(64) T bmx[kBatch], bmy[kBatch], ba[kBatch], bb[kBatch], bc[kBatch], bo[kBatch],
      br[kBatch], bgc[kBatch], bbl[kBatch];
  uint64_t bblocks[kBatch];
  int bj[kBatch];
  uint32_t bid[kBatch];
  const uint32_t* cells = fwd.entry_cells.data() + start;
  // The entries of [lo, hi) with a cell where the forward's Gaussian contributed (the others
  // add nothing), in order, without a branch on each (whether one contributed is unpredictable).
  const auto contributors = [&](int lo, int hi, int* out) {
    int n = 0;
    for (int j = lo; j < hi; ++j) out[n] = j, n += cells[j] != 0;
    return n;
  };
  int bj_next[kBatch];
  int nk = contributors(std::max(0, jmax - kBatch), jmax, bj);
  for (int hi = jmax; hi > 0; hi -= kBatch) {
    const int lo = std::max(0, hi - kBatch);
    // The batch's contributors, each with its blocks: those cells' blocks within its pixel
    // box (the box keeps the backward exact for any record of cells that covers the
    // contributions). The records of the batch after this one, and the accumulators of this
    // one (9 floats at a random place of a per-thread array the size of the Gaussians'
    // count): fetched ahead, the batch's arithmetic then runs without waiting for memory.
    const int nk_next = contributors(std::max(0, lo - kBatch), lo, bj_next);
    for (int k = 0; k < nk_next; ++k)
      __builtin_prefetch(&fwd.packed[size_t(kRec) * fwd.point_list[start + bj_next[k]]]);
    // (Gathered last to first, so that the accumulators fetched last are the ones used
    // last: in-process A/B x0.99 against first to last.)
    for (int k = nk - 1; k >= 0; --k) {
      const int j = bj[k];
      bid[k] = fwd.point_list[start + j];
      __builtin_prefetch(acc + size_t(kNG) * bid[k], 1);
      __builtin_prefetch(acc + size_t(kNG) * bid[k] + kNG - 1, 1);
      const T* rec = &fwd.packed[size_t(kRec) * bid[k]];
      bmx[k] = tile_centre(rec[0], ox);
      bmy[k] = tile_centre(rec[1], oy);
      ba[k] = rec[2], bb[k] = rec[3], bc[k] = rec[4], bo[k] = rec[5];
      br[k] = rec[6], bgc[k] = rec[7], bbl[k] = rec[8];
      bblocks[k] = cells_blocks<BW, BH>(cells[j]) & entry_blocks<BW, BH>(rec, ox, oy);
    }
    for (int k = nk - 1; k >= 0; --k) {
      const int j = bj[k];
      const T mx = bmx[k], a = ba[k], b = bb[k], c = bc[k], o = bo[k];
      const T cr = br[k], cg = bgc[k], cb = bbl[k];
      V s_u{}, s_v{}, s_a{}, s_b{}, s_c{}, s_o{}, s_r{}, s_g{}, s_bl{};
      VI any{};  // lanes where this Gaussian contributed to some pixel of the tile
      // The entry's blocks in the order of their bits.
      uint64_t todo = bblocks[k];
      if (!todo) continue;
      // (The set bits' positions from a table, eight bits a step with no branch on their
      // count, measured 2-4 % slower here than this loop.)
      uint8_t blks[kBlocks];
      int nb = 0;
      for (; todo; todo &= todo - 1) blks[nb++] = uint8_t(__builtin_ctzll(todo));
      const PowerCoeffs<T> pc = power_coeffs(a, b, c);
      const T my = bmy[k];
      // K blocks at a time: their powers and exponentials step by step for all K (the chains
      // side by side), then each block's pixels, then its terms added in block order (the
      // same sums, operation for operation, as one block at a time).
      const auto blocks = [&]<int K>(const uint8_t* bl) {
        V pw[K], dx[K], dy[K], Gv[K];
        T gmx[K], gmy[K], gha[K], gb[K], ghc[K];
        V cols[K], rows[K];
        for (int g = 0; g < K; ++g)
          gmx[g] = mx, gmy[g] = my, gha[g] = pc.ha, gb[g] = pc.hb, ghc[g] = pc.hc,
          cols[g] = lane_cols[bl[g]], rows[g] = lane_rows[bl[g]];
        // The forward's expression: the same skip decisions.
        block_power_group<K>(gmx, gmy, gha, gb, ghc, cols, rows, dx, dy, pw);
        SV::template exp2_group<K>(pw, Gv);
        V w[K], d_r[K], d_g[K], d_bl[K], t_o[K], t_u[K], t_v[K];
        for (int g = 0; g < K; ++g) {
          const int p0 = bl[g] * N;
          const V og = o * Gv[g];
          const V al = SV::min(og, V{} + T(0.99));
          const VI ok = (SI(j) < vload<VI>(last + p0)) & (pw[g] <= T(0)) & (al >= T(1.0f / 255.0f));
          any |= ok;
          const V om = T(1) - al;
          const V Tc = vload<V>(Tt + p0);
          const V Tj = Tc / om;
          const V r0 = vload<V>(R0 + p0), r1 = vload<V>(R1 + p0), r2 = vload<V>(R2 + p0);
          const V d0 = vload<V>(D0 + p0), d1 = vload<V>(D1 + p0), d2 = vload<V>(D2 + p0);
          const V e0 = cr - r0, e1 = cg - r1, e2 = cb - r2;
          const V dLdal = madd(Tj, madd(e2, d2, madd(e1, d1, e0 * d0)), vload<V>(DT + p0) / om);
          // Alpha where the pixel took the Gaussian, 0 elsewhere (there the colour behind stays
          // and the weight is 0).
          const V alo = ok ? al : V{};
          w[g] = alo * Tj;
          d_r[g] = d0, d_g[g] = d1, d_bl[g] = d2;
          // The colour behind the Gaussian's predecessor: al c + (1 - al) r = r + al (c - r).
          vstore(R0 + p0, madd(alo, e0, r0));
          vstore(R1 + p0, madd(alo, e1, r1));
          vstore(R2 + p0, madd(alo, e2, r2));
          vstore(Tt + p0, ok ? Tj : Tc);
          const V dLdog = (ok & (og <= T(0.99))) ? dLdal : V{};
          t_o[g] = Gv[g] * dLdog;
          // pw = -1/2 d^T Q d: dpw/dmean = -(Q d), dpw/d(a, b, c) = -(dx^2 / 2, dx dy, dy^2 / 2).
          // The lanes' dL/dpw dx and dL/dpw dy are summed here; the conic enters once at the end.
          const V dLdpw = og * dLdog;
          t_u[g] = dLdpw * dx[g];
          t_v[g] = dLdpw * dy[g];
        }
        // (The products w d and t_u dx, ... fused into their sums.)
        for (int g = 0; g < K; ++g) {
          s_r = madd(w[g], d_r[g], s_r), s_g = madd(w[g], d_g[g], s_g);
          s_bl = madd(w[g], d_bl[g], s_bl), s_o += t_o[g];
          s_u += t_u[g], s_v += t_v[g];
          s_a = madd(t_u[g], dx[g], s_a), s_c = madd(t_v[g], dy[g], s_c);
          s_b = madd(t_u[g], dy[g], s_b);
        }
      };
      int i = 0;
      for (; i + 4 <= nb; i += 4) blocks.template operator()<4>(blks + i);
      switch (nb - i) {
        case 3:
          blocks.template operator()<3>(blks + i);
          break;
        case 2:
          blocks.template operator()<2>(blks + i);
          break;
        case 1:
          blocks.template operator()<1>(blks + i);
          break;
        default:
          break;
      }
      // Nothing to add where no pixel took this Gaussian (its sums are exact zeros).
      if (!SV::any(any)) continue;
      const V sums[kNG] = {-(a * s_u + b * s_v),
                           -(c * s_v + b * s_u),
                           T(-0.5) * s_a,
                           -s_b,
                           T(-0.5) * s_c,
                           s_o,
                           s_r,
                           s_g,
                           s_bl};
      add_lane_sums<N, T>(sums, acc + size_t(kNG) * bid[k]);
    }
    std::copy(bj_next, bj_next + nk_next, bj);
    nk = nk_next;
  }
}

// The AVX2 kernel in the AVX2 forward's blocks of 4 x 2 pixels.
template <class Res, class Img>
__attribute__((target("avx2,fma"), flatten)) void backward_tile_avx2(
    const Res& fwd, const Img& dLdc, const Img& dLda, bool has_da, const float* bg, float* acc,
    int tile, int tiles_x, int W, int H) {
  backward_tile<4, 2, float>(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
}

// The AVX-512 kernel: the same code compiled with AVX-512VL (32 vector registers, comparisons
// into mask registers), as the forward's; the same gradients bit for bit.
template <class Res, class Img>
__attribute__((target("avx2,fma,avx512f,avx512dq,avx512bw,avx512vl"), flatten)) void
backward_tile_avx512(const Res& fwd, const Img& dLdc, const Img& dLda, bool has_da, const float* bg,
                     float* acc, int tile, int tiles_x, int W, int H) {
  backward_tile<4, 2, float>(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
}

}  // namespace

template <class T>
void backward_tiles(const RasterResultT<T>& fwd, const ImageT<T>& dLdc, const ImageT<T>& dLda,
                    const T* bg, int tiles_x, int tiles_y, Isa isa, int threads,
                    RasterGradsT<T>& gr) {
  const int W = fwd.color.width, H = fwd.color.height;
  const int ntiles = tiles_x * tiles_y;
  const bool has_da = !dLda.data.empty();
  const size_t stride = size_t(kNG) * fwd.radii.size();
  gr.scratch.resize(size_t(threads) * stride);
#pragma omp parallel
  {
    const int tid = omp_get_thread_num();
    T* acc = gr.scratch.data() + size_t(tid) * stride;
    std::fill(acc, acc + stride, T(0));
    // Threads that do not run (nt < threads) must not leave stale data: zero the rest.
#pragma omp single
    for (int th = omp_get_num_threads(); th < threads; ++th)
      std::fill(gr.scratch.data() + size_t(th) * stride,
                gr.scratch.data() + size_t(th + 1) * stride, T(0));
#pragma omp for schedule(dynamic, 2)
    for (int tile = 0; tile < ntiles; ++tile) {
      if constexpr (std::is_same_v<T, float>) {
#if defined(__x86_64__)
        if (isa == Isa::kAvx512) {
          backward_tile_avx512(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
          continue;
        }
#endif
        if (isa != Isa::kBaseline) {
          backward_tile_avx2(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
          continue;
        }
      }
      backward_tile<kCW, 1, T>(fwd, dLdc, dLda, has_da, bg, acc, tile, tiles_x, W, H);
    }
  }
}

template void backward_tiles(const RasterResultT<float>&, const ImageT<float>&,
                             const ImageT<float>&, const float*, int, int, Isa, int,
                             RasterGradsT<float>&);
template void backward_tiles(const RasterResultT<double>&, const ImageT<double>&,
                             const ImageT<double>&, const double*, int, int, Isa, int,
                             RasterGradsT<double>&);

}  // namespace ks::raster
