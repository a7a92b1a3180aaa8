// The rasterizer's forward tile pass (3DGS's render in forward.cu): front-to-back alpha
// compositing of one 16 x 16 tile per task, with the baseline kernel (SSE2: chunks of 4 pixels of
// a row), an AVX2 kernel (blocks of 4 x 2 pixels) and the same with AVX-512VL compiled side by
// side.
#pragma GCC diagnostic ignored "-Wpsabi"
#include <omp.h>

#include <algorithm>
#include <limits>
#include <type_traits>

#include "raster/raster_internal.hpp"

namespace ks::raster {

namespace {

// How many list entries ahead the gathering loop fetches a record.
constexpr uint32_t kPrefetch = 32;
// List entries gathered at a time: their records into the batch's arrays, and each block's
// share of them into the block's list (slots fit a byte).
constexpr int kGather = 252;
// Gaussians a block takes at a time (its list padded with the empty slot kGather).
constexpr int kGroup = 4;

// For each byte of bits, the positions of its set bits as bytes, in order (the rest zero).
struct BitBytes {
  uint64_t b[256];
};
constexpr BitBytes kBitBytes = [] {
  BitBytes t{};
  for (int m = 0; m < 256; ++m) {
    int k = 0;
    for (int bit = 0; bit < 8; ++bit)
      if (m >> bit & 1) t.b[m] |= uint64_t(bit) << (8 * k++);
  }
  return t;
}();

static_assert((kGather + 7) / 8 * 8 <= 256 && kGroup <= 8,
              "slot numbers (whole bytes of eight) fit a byte");

// The cache lines a tile's store_tile will write (colour, alpha; with the backward's state also
// the final transmittance and last contributor), fetched ahead.
template <bool kFull, class Res>
[[gnu::always_inline]] inline void prefetch_tile_outputs(const Res& out, int ox, int oy, int W,
                                                         int H) {
  const int w = std::min(kTS, W - ox);
  for (int r = 0; r < kTS && oy + r < H; ++r) {
    const size_t pix = size_t(oy + r) * W + ox;
    const char* rgb = reinterpret_cast<const char*>(&out.color.data[3 * pix]);
    const size_t bytes = sizeof(out.color.data[0]) * 3 * size_t(w);
    for (size_t b = 0; b < bytes; b += 64) __builtin_prefetch(rgb + b, 1);
    __builtin_prefetch(rgb + bytes - 1, 1);
    __builtin_prefetch(&out.alpha.data[pix], 1);
    __builtin_prefetch(&out.alpha.data[pix + size_t(w) - 1], 1);
    if constexpr (kFull) {
      __builtin_prefetch(&out.final_T[pix], 1);
      __builtin_prefetch(&out.final_T[pix + size_t(w) - 1], 1);
      __builtin_prefetch(&out.n_contrib[pix], 1);
      __builtin_prefetch(&out.n_contrib[pix + size_t(w) - 1], 1);
    }
  }
}

// One tile of the forward pass. One SIMD vector is a block of BW x BH pixels (BW columns of BH
// rows); the tile's pixel state is kept block by block (block_index). kFull: also the backward's
// state (last contributor, final transmittance); kDepth: also the expected depth. Every block shape
// does the same arithmetic per pixel, operation for operation (madd fused on 8 lanes), so the
// AVX2 and AVX-512 kernels give the same image, and the baseline's agrees up to rounding.
//
// The tile's list is taken kGather entries at a time: the records of the entries whose box holds
// a block still to be done are copied into the batch (structure of arrays) and each such block
// gets the entry's slot in its own list. Then each block runs through its list with its pixels'
// state in registers, in list order (so each pixel sees the same Gaussians in the same order as
// entry by entry), and stops as soon as all its pixels are finished. kFull also records, per
// entry, the cells where the Gaussian contributed to a pixel (entry_cells).
template <int BW, int BH, bool kFull, bool kDepth, class T, class Res>
[[gnu::always_inline]] inline void composite_tile(Res& out, int tile, int tiles_x, int W, int H,
                                                  const T* bg) {
  constexpr int N = BW * BH, kBlocks = kTilePixels / N;
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  // The tile's output lines fetched while it composites, so that store_tile finds them in the
  // cache (in-process A/B on the bench scene, three sets: compositing x0.979-0.988 with the
  // backward's state, x0.978-0.989 image only; playback x0.991-0.992. Non-temporal stores
  // instead: x1.27 / x1.21).
  prefetch_tile_outputs<kFull>(out, ox, oy, W, H);
  alignas(64) T Tt[kTilePixels], C0[kTilePixels], C1[kTilePixels], C2[kTilePixels], Dp[kTilePixels];
  using SV = Simd<T, N>;
  using V = typename SV::V;
  using VI = typename SV::I;
  using SI = typename SV::S;
  // A pixel is finished (transmittance would fall below 1e-4, or outside the image) when its
  // Tt is negative; |Tt| is its transmittance.
  alignas(64) SI last[kTilePixels];
  // The blocks with a pixel still to be done, as bits (block br * kTS / BW + q).
  uint64_t live = 0;
  for (int r = 0; r < kTS; ++r)
    for (int c = 0; c < kTS; ++c) {
      const int p = block_index<BW, BH>(c, r);
      const bool in = ox + c < W && oy + r < H;
      Tt[p] = in ? T(1) : T(-1), C0[p] = C1[p] = C2[p] = Dp[p] = 0, last[p] = 0;
      live |= uint64_t(in) << (p / N);
    }
  // The batch: per slot the Gaussian's centre (tile-local, less half a pixel), its conic as
  // power_coeffs, opacity, colour, depth and its 1-based position in the tile's list; per block
  // the slots that cover it.
  constexpr int kSlots = kGather + 1;
  alignas(64) T gx[kSlots], gy[kSlots], gha[kSlots], gb[kSlots], ghc[kSlots], go[kSlots],
      gr[kSlots], gg[kSlots], gbl[kSlots], gz[kSlots];
  alignas(64) SI gidx[kSlots];
  alignas(64) uint32_t gcells[kFull ? kSlots : 1];  // kFull: the cells each slot contributed to
  uint32_t* const cells_out = kFull ? out.entry_cells.data() : nullptr;
  // (Room for a whole group of padding, and for the eight bytes kByMasks stores at a time.)
  alignas(64) uint8_t lists[kBlocks][kGather + 8];
  gx[kGather] = gy[kGather] = gha[kGather] = gb[kGather] = ghc[kGather] = go[kGather] = 0;
  gr[kGather] = gg[kGather] = gbl[kGather] = gz[kGather] = 0;
  gidx[kGather] = 0;
  int nlist[kBlocks];
  // With 32 blocks of 8 lanes, each slot's blocks as bits, turned into the blocks' lists by
  // the lanes' sign bits (8 slots a step) instead of one list append per block and slot.
  constexpr bool kByMasks = kHaveSignBits8 && kBlocks == 32 && N == 8 && std::is_same_v<T, float>;
  alignas(64) uint32_t slot_blocks[kByMasks ? kGather + 8 : 1];
  const V col_off = block_columns<V, BW, BH>(), row_off = block_rows<V, BW, BH>();
  const VI sign = VI{} + std::numeric_limits<SI>::min();  // T's sign bit in every lane
  const uint32_t start = out.tile_ranges[2 * tile], end = out.tile_ranges[2 * tile + 1];
  for (uint32_t e = start; e < std::min(end, start + kPrefetch); ++e)
    __builtin_prefetch(&out.packed[size_t(kRec) * out.point_list[e]]);
  uint32_t e0 = start;
  for (; e0 < end && live; e0 += kGather) {
    const uint32_t e1 = std::min(end, e0 + uint32_t(kGather));
    if constexpr (!kByMasks)
      for (uint64_t m = live; m; m &= m - 1) nlist[__builtin_ctzll(m)] = 0;
    int n = 0;
    uint64_t covered = 0;
    for (uint32_t e = e0; e < e1; ++e) {
      // The records are gathered through the tile's list: fetch a few ahead.
      if (e + kPrefetch < end)
        __builtin_prefetch(&out.packed[size_t(kRec) * out.point_list[e + kPrefetch]]);
      const T* rec = &out.packed[size_t(kRec) * out.point_list[e]];
      uint64_t todo = live & entry_blocks<BW, BH>(rec, ox, oy);
      // Image only, the entry's slot is written whether or not it has a live block and kept
      // only if it has one (below): no branch on it, which turns unpredictable as the tile's
      // blocks finish (in-process A/B: image-only compositing x0.97; with the backward's
      // bookkeeping the skipped entries' extra work costs more than the branch, x1.03).
      constexpr bool kBranchless = kByMasks && !kFull;
      if (!kBranchless && !todo) {
        if constexpr (kFull) cells_out[e] = 0;
        continue;
      }
      gx[n] = tile_centre(rec[0], ox), gy[n] = tile_centre(rec[1], oy);
      const PowerCoeffs<T> pc = power_coeffs(rec[2], rec[3], rec[4]);
      gha[n] = pc.ha, gb[n] = pc.hb, ghc[n] = pc.hc, go[n] = rec[5];
      gr[n] = rec[6], gg[n] = rec[7], gbl[n] = rec[8], gz[n] = rec[9];
      gidx[n] = SI(e - start + 1);
      if constexpr (kFull) gcells[n] = 0;
      if constexpr (kByMasks) {
        slot_blocks[n] = uint32_t(todo);
        covered |= todo;
        if constexpr (kBranchless) {
          n += todo != 0;
          continue;
        }
      } else {
        for (; todo; todo &= todo - 1) {
          const int blk = __builtin_ctzll(todo);
          lists[blk][nlist[blk]++] = uint8_t(n);
        }
      }
      ++n;
    }
    if (!n) continue;
    if constexpr (kByMasks) {
      for (int k = n; k % 8; ++k) slot_blocks[k] = 0;
      for (uint64_t m = covered; m; m &= m - 1) {
        const int blk = __builtin_ctzll(m);
        uint8_t* li = lists[blk];
        int cnt = 0;
        // Eight slots a step: their bits for this block, and the set ones' slot numbers as
        // eight bytes from a table (kBitBytes), stored whole and advanced by their count.
        for (int s0 = 0; s0 < n; s0 += 8) {
          const VI v = vload<VI>(slot_blocks + s0) << (31 - blk);
          const uint32_t bits = sign_bits8(v);
          const uint64_t idx = kBitBytes.b[bits] + 0x0101010101010101ull * uint64_t(s0);
          std::memcpy(li + cnt, &idx, sizeof idx);
          cnt += __builtin_popcount(bits);
        }
        nlist[blk] = cnt;
      }
    }
    for (uint64_t m = kByMasks ? live & covered : live; m; m &= m - 1) {
      const int blk = __builtin_ctzll(m);
      const int cnt = nlist[blk];
      if (!cnt) continue;
      V bcols, brows;
      block_lanes<BW, BH>(blk, col_off, row_off, bcols, brows);
      const int p0 = blk * N;
      [[maybe_unused]] const uint32_t cells = block_cells<BW, BH>(blk);
      V Tb = vload<V>(Tt + p0), c0 = vload<V>(C0 + p0), c1 = vload<V>(C1 + p0),
        c2 = vload<V>(C2 + p0), dp{};
      VI lb{};
      if constexpr (kFull) lb = vload<VI>(last + p0);
      if constexpr (kDepth) dp = vload<V>(Dp + p0);
      // The list padded to whole groups with the empty slot (opacity 0: no pixel takes it),
      // by one store of a whole group's worth (no loop whose count is cnt's remainder).
      uint8_t* li = lists[blk];
      static_assert(kGroup == 4, "one 4-byte store pads a group");
      const uint32_t pad = 0x01010101u * uint32_t(kGather);
      std::memcpy(li + cnt, &pad, sizeof pad);
      // Each Gaussian's alpha over the block (independent of the pixels' state, so the
      // group's exponentials overlap).
      const auto alphas = [&](int i, V* al, VI* in) {
        V pw[kGroup], ex[kGroup];
        T mx[kGroup], my[kGroup], ha[kGroup], hb[kGroup], hc[kGroup];
        for (int k = 0; k < kGroup; ++k) {
          const int j = li[i + k];
          mx[k] = gx[j], my[k] = gy[j], ha[k] = gha[j], hb[k] = gb[j], hc[k] = ghc[j];
        }
        V dx[kGroup], dy[kGroup], cols[kGroup], rows[kGroup];
        for (int k = 0; k < kGroup; ++k) cols[k] = bcols, rows[k] = brows;
        block_power_group<kGroup>(mx, my, ha, hb, hc, cols, rows, dx, dy, pw);
        SV::template exp2_group<kGroup>(pw, ex);
        for (int k = 0; k < kGroup; ++k) {
          const V og = go[li[i + k]] * ex[k];
          al[k] = SV::min(og, V{} + T(0.99));
          in[k] = (pw[k] <= T(0)) & (al[k] >= T(1.0f / 255.0f));
          // Image only: alpha 0 outside the range (the pixel's state then stays as it is).
          if constexpr (!kFull) al[k] = (V)((VI)al[k] & in[k]);
        }
      };
      // The next group's alphas are computed before this group is composited, so that the
      // independent work sits beside the transmittance's chain in the instruction stream.
      V al[kGroup], al_next[kGroup]{};
      VI in[kGroup], in_next[kGroup]{};
      alphas(0, al, in);
      for (int i = 0; i < cnt; i += kGroup) {
        if (i + kGroup < cnt) alphas(i + kGroup, al_next, in_next);
        for (int k = 0; k < kGroup; ++k) {
          // A pixel takes the Gaussian (con) when it is in its alpha range and the
          // transmittance stays above 1e-4; a finished pixel (Tp < 0) gives Tn <= 0, so it never
          // does. One that would fall below finishes: Tp becomes -Tp, which for a pixel in
          // range is Tp with the sign bit set (a finished one's Tp already has it). The
          // transmittance's chain is then a product, a comparison and a blend.
          // Image only, alpha is 0 outside the range: there Tn is Tp and w is 0, the same state
          // without the range in the chain (only the last contributor and the cells need it).
          const int j = li[i + k];
          const V Tp = Tb;
          const V Tn = Tp * (T(1) - al[k]);
          const VI con = kFull ? in[k] & ~(Tn < T(1e-4)) : Tn >= T(1e-4);
          const V w = con ? al[k] * Tp : V{};
          c0 = madd(w, splat<V>(gr[j]), c0);
          c1 = madd(w, splat<V>(gg[j]), c1);
          c2 = madd(w, splat<V>(gbl[j]), c2);
          if constexpr (kDepth) dp = madd(w, splat<V>(gz[j]), dp);
          Tb = con ? Tn : (V)((VI)Tp | (kFull ? in[k] & sign : sign));
          if constexpr (kFull) {
            lb = (con & SI(gidx[j])) | (~con & lb);
            if constexpr (BW <= kCellW && BH <= kCellH)
              gcells[j] |= SV::any(con) ? cells : 0u;  // the block lies in one cell
            else
              gcells[j] |= lanes_cells<BW, BH>(blk, con);
          }
        }
        // A finished pixel takes nothing more, so checking once a group changes nothing.
        if (SV::all_negative(Tb)) {
          live &= ~(uint64_t(1) << blk);
          break;
        }
        for (int k = 0; k < kGroup; ++k) al[k] = al_next[k], in[k] = in_next[k];
      }
      vstore(Tt + p0, Tb), vstore(C0 + p0, c0), vstore(C1 + p0, c1), vstore(C2 + p0, c2);
      if constexpr (kFull) vstore(last + p0, lb);
      if constexpr (kDepth) vstore(Dp + p0, dp);
    }
    if constexpr (kFull)
      for (int k = 0; k < n; ++k) cells_out[start + uint32_t(gidx[k]) - 1] = gcells[k];
  }
  // Entries after the tile finished take no pixel.
  if constexpr (kFull) std::fill(cells_out + std::min(e0, end), cells_out + end, 0u);
  store_tile<T, SI, block_index<BW, BH>>(out, ox, oy, bg, Tt, C0, C1, C2, Dp, last, kFull, kDepth);
}

// The AVX2 kernel: one 8-lane vector is a block of 4 x 2 pixels, which a small Gaussian covers
// in fewer steps than rows of eight (on the bench scene and a reconstructed avatar, 15-19 %
// fewer block visits by the Gaussians' rectangles).
template <bool kFull, bool kDepth, class Res>
__attribute__((target("avx2,fma"), flatten)) void composite_tile_avx2(Res& out, int tile,
                                                                      int tiles_x, int W, int H,
                                                                      const float* bg) {
  composite_tile<4, 2, kFull, kDepth, float>(out, tile, tiles_x, W, H, bg);
}

// The AVX-512 kernel: the AVX2 kernel's code (the same blocks of 4 x 2 pixels on 8 lanes)
// compiled with AVX-512VL, which gives it 32 vector registers instead of 16 (the walk's state,
// the group being composited and the next group's alphas fit without spilling) and comparisons
// into mask registers. The same fused multiply-adds (madd) and no others: the same images.
template <bool kFull, bool kDepth, class Res>
__attribute__((target("avx2,fma,avx512f,avx512dq,avx512bw,avx512vl"), flatten)) void
composite_tile_avx512(Res& out, int tile, int tiles_x, int W, int H, const float* bg) {
  composite_tile<4, 2, kFull, kDepth, float>(out, tile, tiles_x, W, H, bg);
}

// A tile no Gaussian touches: colour = background, alpha 0 (and depth 0, final transmittance 1,
// no contributor), as store_tile leaves it after compositing nothing. bg_row: the background
// colour of a whole tile row (kTS pixels, 3 values each), copied row by row.
template <class T>
void fill_empty_tile(RasterResultT<T>& out, int tile, int tiles_x, int W, int H, const T* bg_row,
                     bool full, bool depth) {
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  const int w = std::min(kTS, W - ox);
  for (int r = 0; r < kTS && oy + r < H; ++r) {
    const size_t pix = size_t(oy + r) * W + ox;
    std::memcpy(&out.color.data[3 * pix], bg_row, sizeof(T) * 3 * size_t(w));
    std::fill_n(&out.alpha.data[pix], w, T(0));
    if (depth) std::fill_n(&out.depth.data[pix], w, T(0));
    if (full) {
      std::fill_n(&out.final_T[pix], w, T(1));
      std::fill_n(&out.n_contrib[pix], w, 0u);
    }
  }
}

// One tile by the kernel of `isa` (the double instantiation has the baseline's only).
template <bool kFull, bool kDepth, class T>
void composite_tile_isa(RasterResultT<T>& out, int tile, int tiles_x, int W, int H, const T* bg,
                        Isa isa) {
  if constexpr (std::is_same_v<T, float>) {
#if defined(__x86_64__)
    if (isa == Isa::kAvx512)
      return composite_tile_avx512<kFull, kDepth>(out, tile, tiles_x, W, H, bg);
#endif
    if (isa != Isa::kBaseline)
      return composite_tile_avx2<kFull, kDepth>(out, tile, tiles_x, W, H, bg);
  }
  composite_tile<kCW, 1, kFull, kDepth, T>(out, tile, tiles_x, W, H, bg);
}

}  // namespace

template <class T>
void composite_tiles(RasterResultT<T>& out, int tiles_x, int tiles_y, const T* bg, Isa isa) {
  const int W = out.color.width, H = out.color.height;
  const int ntiles = tiles_x * tiles_y;
  const bool full = !out.image_only, depth = !out.depth.data.empty();
  if (full) out.entry_cells.resize(out.point_list.size());
  T bg_row[3 * kTS];
  for (int k = 0; k < 3 * kTS; ++k) bg_row[k] = bg[k % 3];
  // Tiles a thread takes at a time: a run along a tile row, whose lists (point_list, and
  // entry_cells written beside it) lie one after another, so that one core reads and writes
  // them as continuous streams (in-process A/B on the bench scene against runs of 2:
  // compositing x0.95 with the backward's state, x0.97 image only; playback x0.97; blocks of
  // 2 x 2 tiles, which share more records but jump between rows, x1.04), and at least 8 runs a
  // thread for the balance.
  const int run = std::clamp(ntiles / (8 * omp_get_max_threads()), 2, 16);
#pragma omp parallel for schedule(dynamic, run)
  for (int tile = 0; tile < ntiles; ++tile) {
    if (out.tile_ranges[2 * tile] == out.tile_ranges[2 * tile + 1]) {
      // No Gaussian: the background, what the kernels would store for it.
      fill_empty_tile(out, tile, tiles_x, W, H, bg_row, full, depth);
      continue;
    }
    if (full)
      depth ? composite_tile_isa<true, true>(out, tile, tiles_x, W, H, bg, isa)
            : composite_tile_isa<true, false>(out, tile, tiles_x, W, H, bg, isa);
    else
      depth ? composite_tile_isa<false, true>(out, tile, tiles_x, W, H, bg, isa)
            : composite_tile_isa<false, false>(out, tile, tiles_x, W, H, bg, isa);
  }
}

template void composite_tiles(RasterResultT<float>&, int, int, const float*, Isa);
template void composite_tiles(RasterResultT<double>&, int, int, const double*, Isa);

}  // namespace ks::raster
