// The rasterizer's forward tile pass (3DGS's render in forward.cu): front-to-back alpha
// compositing of one 16 x 16 tile per task, with the baseline kernel (SSE2: chunks of 4 pixels of
// a row) and an AVX2 kernel (blocks of 4 x 2 pixels) compiled side by side.
#pragma GCC diagnostic ignored "-Wpsabi"
#include <omp.h>

#include <algorithm>
#include <type_traits>

#include "raster/raster_internal.hpp"

namespace ks::raster {

namespace {

// How many list entries ahead the tile loop fetches a record.
constexpr uint32_t kPrefetch = 8;

// One tile of the forward pass. One SIMD vector is a block of BW x BH pixels (BW columns of BH
// rows); the tile's pixel state is kept block by block (block_index). kFull: also the expected
// depth and the backward's state (last contributor, final transmittance). Every block shape
// does the same arithmetic per pixel, operation for operation, so all give the same image.
template <int BW, int BH, bool kFull, class T, class Res>
[[gnu::always_inline]] inline void composite_tile(Res& out, int tile, int tiles_x, int W, int H,
                                                  const T* bg) {
  constexpr int N = BW * BH, kBPR = kTS / BW, kBlocks = kTilePixels / N;
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  alignas(64) T Tt[kTilePixels], C0[kTilePixels], C1[kTilePixels], C2[kTilePixels], Dp[kTilePixels];
  using SV = Simd<T, N>;
  using V = typename SV::V;
  using VI = typename SV::I;
  using SI = typename SV::S;
  // A pixel is finished (transmittance would fall below 1e-4, or outside the image) when its
  // Tt is negative; |Tt| is its transmittance.
  alignas(64) SI last[kTilePixels];
  int block_live[kBlocks];  // live pixels per block
  int tile_live = 0;
  for (int q = 0; q < kBlocks; ++q) block_live[q] = 0;
  for (int r = 0; r < kTS; ++r)
    for (int c = 0; c < kTS; ++c) {
      const int p = block_index<BW, BH>(c, r);
      const bool in = ox + c < W && oy + r < H;
      Tt[p] = in ? T(1) : T(-1), C0[p] = C1[p] = C2[p] = Dp[p] = 0, last[p] = 0;
      block_live[p / N] += in;
      tile_live += in;
    }
  // The live blocks as bits (block br * kBPR + q), and a bit in each block row's first column:
  // a Gaussian whose box holds no live block is skipped whole (at a silhouette the background
  // pixels keep a tile going through the body's deeper layers).
  uint64_t live = 0;
  for (int q = 0; q < kBlocks; ++q) live |= uint64_t(block_live[q] > 0) << q;
  const V col_off = block_columns<V, BW, BH>(), row_off = block_rows<V, BW, BH>();
  const uint32_t start = out.tile_ranges[2 * tile], end = out.tile_ranges[2 * tile + 1];
  for (uint32_t e = start; e < end && tile_live > 0; ++e) {
    // The records are gathered through the tile's list: fetch a few ahead.
    if (e + kPrefetch < end)
      __builtin_prefetch(&out.packed[size_t(kRec) * out.point_list[e + kPrefetch]]);
    const T* rec = &out.packed[size_t(kRec) * out.point_list[e]];
    const T mx = rec[0] - T(ox), my = rec[1] - T(oy);
    const T a = rec[2], b = rec[3], c = rec[4], o = rec[5];
    const T cr = rec[6], cg = rec[7], cb = rec[8], zz = rec[9];
    const int q0 = std::max(int(rec[10]) - ox, 0) / BW;
    const int q1 = std::min(int(rec[11]) - ox, kTS - 1) / BW;
    const int br0 = std::max(int(rec[12]) - oy, 0) / BH;
    const int br1 = std::min(int(rec[13]) - oy, kTS - 1) / BH;
    // The live blocks of the Gaussian's box, visited by their bits (no nested loops of varying
    // length to mispredict; a block finished meanwhile is not in the box again).
    uint64_t todo = live & box_blocks<BW, BH>(q0, q1, br0, br1);
    if (!todo) continue;
    const int32_t idx1 = int32_t(e - start) + 1;
    const T ha = T(0.5) * a, hc = T(0.5) * c;
    for (; todo; todo &= todo - 1) {
      const int blk = __builtin_ctzll(todo);
      const int br = blk / kBPR, q = blk % kBPR;
      const int p0 = blk * N;
      V dx, dy;
      const V pw = block_power<BW, BH>(mx, my, ha, b, hc, br, q, col_off, row_off, dx, dy);
      const V og = o * SV::exp(pw);
      const V al = og < T(0.99) ? og : V{} + T(0.99);
      const V Tp = vload<V>(Tt + p0);
      const VI ok = (pw <= T(0)) & (al >= T(1.0f / 255.0f)) & (Tp > T(0));
      const V Tn = Tp * (T(1) - al);
      const VI term = ok & (Tn < T(1e-4));
      const VI con = ok & ~term;
      const V w = con ? al * Tp : V{};
      vstore(C0 + p0, vload<V>(C0 + p0) + w * cr);
      vstore(C1 + p0, vload<V>(C1 + p0) + w * cg);
      vstore(C2 + p0, vload<V>(C2 + p0) + w * cb);
      if constexpr (kFull) vstore(Dp + p0, vload<V>(Dp + p0) + w * zz);
      vstore(Tt + p0, con ? Tn : (term ? -Tp : Tp));
      if constexpr (kFull) vstore(last + p0, (con & SI(idx1)) | (~con & vload<VI>(last + p0)));
      const int nterm = SV::count(term);
      if (nterm) {
        block_live[blk] -= nterm;
        tile_live -= nterm;
        if (block_live[blk] == 0) live &= ~(uint64_t(1) << blk);
      }
    }
  }
  store_tile<T, SI, block_index<BW, BH>>(out, ox, oy, bg, Tt, C0, C1, C2, Dp, last, kFull);
}

// The AVX2 kernel: one 8-lane vector is a block of 4 x 2 pixels, which a small Gaussian covers
// in fewer steps than rows of eight (on the bench scene and a reconstructed avatar, 15-19 %
// fewer block visits by the Gaussians' rectangles).
template <bool kFull, class Res>
__attribute__((target("avx2"), flatten)) void composite_tile_avx2(Res& out, int tile, int tiles_x,
                                                                  int W, int H, const float* bg) {
  composite_tile<4, 2, kFull, float>(out, tile, tiles_x, W, H, bg);
}

// A tile no Gaussian touches: colour = background, alpha 0 (and depth 0, final transmittance 1,
// no contributor), as store_tile leaves it after compositing nothing.
template <class T>
void fill_empty_tile(RasterResultT<T>& out, int tile, int tiles_x, int W, int H, const T* bg,
                     bool full) {
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  const int w = std::min(kTS, W - ox);
  for (int r = 0; r < kTS && oy + r < H; ++r) {
    const size_t pix = size_t(oy + r) * W + ox;
    T* c = &out.color.data[3 * pix];
    for (int k = 0; k < w; ++k) c[3 * k] = bg[0], c[3 * k + 1] = bg[1], c[3 * k + 2] = bg[2];
    std::fill_n(&out.alpha.data[pix], w, T(0));
    if (full) {
      std::fill_n(&out.depth.data[pix], w, T(0));
      std::fill_n(&out.final_T[pix], w, T(1));
      std::fill_n(&out.n_contrib[pix], w, 0u);
    }
  }
}

}  // namespace

template <class T>
void composite_tiles(RasterResultT<T>& out, int tiles_x, int tiles_y, const T* bg, Isa isa) {
  const int W = out.color.width, H = out.color.height;
  const int ntiles = tiles_x * tiles_y;
  const bool full = !out.image_only;
#pragma omp parallel for schedule(dynamic, 2)
  for (int tile = 0; tile < ntiles; ++tile) {
    if (out.tile_ranges[2 * tile] == out.tile_ranges[2 * tile + 1]) {
      // No Gaussian: the background, what the kernels would store for it.
      fill_empty_tile(out, tile, tiles_x, W, H, bg, full);
      continue;
    }
    if constexpr (std::is_same_v<T, float>) {
#if defined(__x86_64__)
      if (isa == Isa::kAvx512) {
        composite_tile_avx512(out, tile, tiles_x, W, H, bg, full);
        continue;
      }
#endif
      if (isa != Isa::kBaseline) {
        if (full)
          composite_tile_avx2<true>(out, tile, tiles_x, W, H, bg);
        else
          composite_tile_avx2<false>(out, tile, tiles_x, W, H, bg);
        continue;
      }
    }
    if (full)
      composite_tile<kCW, 1, true, T>(out, tile, tiles_x, W, H, bg);
    else
      composite_tile<kCW, 1, false, T>(out, tile, tiles_x, W, H, bg);
  }
}

template void composite_tiles(RasterResultT<float>&, int, int, const float*, Isa);
template void composite_tiles(RasterResultT<double>&, int, int, const double*, Isa);

}  // namespace ks::raster
