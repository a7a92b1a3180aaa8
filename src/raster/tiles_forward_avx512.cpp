// The rasterizer's forward tile pass with AVX-512 (chosen at run time where the CPU has it): one
// 16-lane vector is a whole tile row, so a Gaussian costs one vector step per row it covers,
// with the lane masks in mask registers. The arithmetic is the baseline kernel's, operation for
// operation (this file is compiled without floating-point contraction), so the three kernels
// give the same images bit for bit.
// GCC 12 reports its own AVX-512 intrinsics' undefined pass-through operands as maybe
// uninitialised (a known false positive).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <omp.h>

#include <algorithm>

#include "raster/raster_internal.hpp"
#include "raster/simd_avx512.hpp"

namespace ks::raster {

#if defined(__x86_64__)

__attribute__((target("avx512f,avx512dq,avx512bw,avx512vl"))) void composite_tile_avx512(
    RasterResultT<float>& out, int tile, int tiles_x, int W, int H, const float* bg, bool full) {
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  alignas(64) float Tt[kTilePixels], C0[kTilePixels], C1[kTilePixels], C2[kTilePixels],
      Dp[kTilePixels];
  alignas(64) int32_t last[kTilePixels];
  // A pixel is finished (transmittance would fall below 1e-4, or outside the image) when its
  // Tt is negative; |Tt| is its transmittance. row_live: the live pixels of each row, as bits.
  uint16_t row_live[kTS];
  int tile_live = 0;
  const int wcols = std::min(kTS, W - ox);
  const __mmask16 cols_in = __mmask16((1u << std::max(wcols, 0)) - 1u);
  for (int r = 0; r < kTS; ++r) {
    const bool row_in = oy + r < H;
    const __mmask16 in = row_in ? cols_in : __mmask16(0);
    _mm512_store_ps(Tt + r * kTS,
                    _mm512_mask_blend_ps(in, _mm512_set1_ps(-1.f), _mm512_set1_ps(1.f)));
    _mm512_store_ps(C0 + r * kTS, _mm512_setzero_ps());
    _mm512_store_ps(C1 + r * kTS, _mm512_setzero_ps());
    _mm512_store_ps(C2 + r * kTS, _mm512_setzero_ps());
    _mm512_store_ps(Dp + r * kTS, _mm512_setzero_ps());
    _mm512_store_si512(last + r * kTS, _mm512_setzero_si512());
    row_live[r] = in;
    tile_live += __builtin_popcount(unsigned(in));
  }
  const __m512 iota = _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const uint32_t start = out.tile_ranges[2 * tile], end = out.tile_ranges[2 * tile + 1];
  uint32_t e = start;
  for (; e < end && tile_live > 0; ++e) {
    const float* rec = &out.packed[size_t(kRec) * out.point_list[e]];
    const float mx = rec[0] - float(ox), my = rec[1] - float(oy);
    const float a = rec[2], b = rec[3], c = rec[4], o = rec[5];
    const int x0 = std::max(int(rec[10]) - ox, 0), x1 = std::min(int(rec[11]) - ox, kTS - 1);
    const int y0 = std::max(int(rec[12]) - oy, 0), y1 = std::min(int(rec[13]) - oy, kTS - 1);
    // The pixel columns of the Gaussian's rectangle.
    const __mmask16 cols = __mmask16(((2u << x1) - 1u) & ~((1u << x0) - 1u));
    const int32_t idx1 = int32_t(e - start) + 1;
    // dx and 0.5 a dx dx are the same on every row.
    const __m512 dx = _mm512_sub_ps(_mm512_set1_ps((mx - 0.0f) - 0.5f), iota);
    const __m512 adx2 = _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5f * a), dx), dx);
    const __m512 vo = _mm512_set1_ps(o), vr = _mm512_set1_ps(rec[6]), vg = _mm512_set1_ps(rec[7]),
                 vb = _mm512_set1_ps(rec[8]), vz = _mm512_set1_ps(rec[9]);
    const __m512i vidx = _mm512_set1_epi32(idx1);
    uint32_t cells = 0;  // full: the cells of 4 x 2 pixels where it contributed (entry_cells)
    for (int r = y0; r <= y1; ++r) {
      const __mmask16 live = __mmask16(row_live[r] & cols);
      if (!live) continue;
      const float dy = my - (float(r) + 0.5f);
      const float cdy = 0.5f * c * dy * dy, bdy = b * dy;
      const __m512 pw = _mm512_sub_ps(
          _mm512_xor_ps(_mm512_add_ps(adx2, _mm512_set1_ps(cdy)), _mm512_set1_ps(-0.0f)),
          _mm512_mul_ps(_mm512_set1_ps(bdy), dx));
      const __m512 og = _mm512_mul_ps(vo, exp16(pw));
      const __m512 al = _mm512_min_ps(og, _mm512_set1_ps(0.99f));
      float* pt = Tt + r * kTS;
      const __m512 Tp = _mm512_load_ps(pt);
      const __mmask16 ok = _mm512_mask_cmp_ps_mask(
          _mm512_mask_cmp_ps_mask(live, pw, _mm512_setzero_ps(), _CMP_LE_OQ), al,
          _mm512_set1_ps(1.0f / 255.0f), _CMP_GE_OQ);
      const __m512 Tn = _mm512_mul_ps(Tp, _mm512_sub_ps(_mm512_set1_ps(1.f), al));
      const __mmask16 term = _mm512_mask_cmp_ps_mask(ok, Tn, _mm512_set1_ps(1e-4f), _CMP_LT_OQ);
      const __mmask16 con = ok & ~term;
      // Without a branch on `con` (it is as often empty as not at a Gaussian's edge rows).
      const __m512 w = _mm512_maskz_mul_ps(con, al, Tp);
      float* p0 = C0 + r * kTS;
      float* p1 = C1 + r * kTS;
      float* p2 = C2 + r * kTS;
      _mm512_store_ps(p0, _mm512_add_ps(_mm512_load_ps(p0), _mm512_mul_ps(w, vr)));
      _mm512_store_ps(p1, _mm512_add_ps(_mm512_load_ps(p1), _mm512_mul_ps(w, vg)));
      _mm512_store_ps(p2, _mm512_add_ps(_mm512_load_ps(p2), _mm512_mul_ps(w, vb)));
      if (full) {  // the same every call: a predicted branch
        float* pd = Dp + r * kTS;
        _mm512_store_ps(pd, _mm512_add_ps(_mm512_load_ps(pd), _mm512_mul_ps(w, vz)));
        _mm512_mask_store_epi32(last + r * kTS, con, vidx);
        const uint32_t m = con;  // the row's four cells: any lane of each group of 4
        const uint32_t quads = uint32_t((m & 0xfu) != 0) | uint32_t((m & 0xf0u) != 0) << 1 |
                               uint32_t((m & 0xf00u) != 0) << 2 | uint32_t((m & 0xf000u) != 0) << 3;
        cells |= quads << ((r / kCellH) * kCellsPerRow);
      }
      __m512 Tnew = _mm512_mask_mov_ps(Tp, con, Tn);
      if (term) {
        Tnew = _mm512_mask_sub_ps(Tnew, term, _mm512_setzero_ps(), Tp);
        row_live[r] = uint16_t(row_live[r] & ~term);
        tile_live -= __builtin_popcount(unsigned(term));
      }
      _mm512_store_ps(pt, Tnew);
    }
    if (full) out.entry_cells[e] = cells;
  }
  // Entries after the tile finished take no pixel.
  if (full) std::fill(out.entry_cells.begin() + e, out.entry_cells.begin() + end, 0u);
  store_tile(out, ox, oy, bg, Tt, C0, C1, C2, Dp, last, full);
}

#endif

}  // namespace ks::raster
