// The rasterizer's backward tile pass with AVX-512 (chosen at run time where the CPU has it):
// the baseline kernel's reverse compositing with a whole 16-pixel tile row per vector and the
// lane masks in mask registers; an entry that took no pixel in the forward and rows whose cells
// (entry_cells) hold none of its contributions are skipped, and the per-Gaussian sums are
// reduced across the lanes once per tile. Compiled without floating-point contraction, like
// the forward kernel it reverses.
// GCC 12 reports its own AVX-512 intrinsics' undefined pass-through operands as maybe
// uninitialised (a known false positive).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <algorithm>

#include "raster/raster_internal.hpp"
#include "raster/simd_avx512.hpp"

namespace ks::raster {

#if defined(__x86_64__)

__attribute__((target("avx512f,avx512dq,avx512bw,avx512vl"))) void backward_tile_avx512(
    const RasterResultT<float>& fwd, const ImageT<float>& dLdc, const ImageT<float>& dLda,
    bool has_da, const float* bg, float* acc, int tile, int tiles_x, int W, int H) {
  const uint32_t start = fwd.tile_ranges[2 * tile], end = fwd.tile_ranges[2 * tile + 1];
  if (start == end) return;
  const int ox = (tile % tiles_x) * kTS, oy = (tile / tiles_x) * kTS;
  alignas(64) float Tt[kTilePixels], Tf[kTilePixels], R0[kTilePixels], R1[kTilePixels],
      R2[kTilePixels], D0[kTilePixels], D1[kTilePixels], D2[kTilePixels], DA[kTilePixels];
  alignas(64) int32_t last[kTilePixels];
  int row_max[kTS];  // max over the row's pixels of last contributor + 1
  int jmax = 0;
  for (int r = 0; r < kTS; ++r) {
    row_max[r] = 0;
    for (int c = 0; c < kTS; ++c) {
      const int p = r * kTS + c;
      if (ox + c < W && oy + r < H) {
        const size_t pix = size_t(oy + r) * W + ox + c;
        Tt[p] = Tf[p] = fwd.final_T[pix];
        last[p] = int32_t(fwd.n_contrib[pix]);
        D0[p] = dLdc.data[3 * pix], D1[p] = dLdc.data[3 * pix + 1], D2[p] = dLdc.data[3 * pix + 2];
        DA[p] = has_da ? dLda.data[pix] : 0.f;
      } else {
        Tt[p] = Tf[p] = 1, last[p] = 0, D0[p] = D1[p] = D2[p] = DA[p] = 0;
      }
      R0[p] = bg[0], R1[p] = bg[1], R2[p] = bg[2];
      row_max[r] = std::max(row_max[r], int(last[p]));
    }
    jmax = std::max(jmax, row_max[r]);
  }
  const __m512 iota = _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const __m512 one = _mm512_set1_ps(1.f), zero = _mm512_setzero_ps();
  for (int j = jmax - 1; j >= 0; --j) {
    // The cells where the forward's Gaussian took a pixel (none: it adds nothing here).
    const uint32_t cells = fwd.entry_cells[start + j];
    if (!cells) continue;
    const uint32_t id = fwd.point_list[start + j];
    const float* rec = &fwd.packed[size_t(kRec) * id];
    const float mx = rec[0] - float(ox), my = rec[1] - float(oy);
    const float a = rec[2], b = rec[3], c = rec[4], o = rec[5];
    const int x0 = std::max(int(rec[10]) - ox, 0), x1 = std::min(int(rec[11]) - ox, kTS - 1);
    const int y0 = std::max(int(rec[12]) - oy, 0), y1 = std::min(int(rec[13]) - oy, kTS - 1);
    const __mmask16 cols = __mmask16(((2u << x1) - 1u) & ~((1u << x0) - 1u));
    const __m512 dx = _mm512_sub_ps(_mm512_set1_ps((mx - 0.0f) - 0.5f), iota);
    const __m512 adx2 = _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5f * a), dx), dx);
    const __m512 va = _mm512_set1_ps(a), vb = _mm512_set1_ps(b), vc = _mm512_set1_ps(c);
    const __m512 vo = _mm512_set1_ps(o), cr = _mm512_set1_ps(rec[6]), cg = _mm512_set1_ps(rec[7]),
                 cb = _mm512_set1_ps(rec[8]);
    const __m512i vj = _mm512_set1_epi32(j);
    __m512 s_mx = zero, s_my = zero, s_a = zero, s_b = zero, s_c = zero, s_o = zero, s_r = zero,
           s_g = zero, s_bl = zero;
    bool any = false;
    for (int r = y0; r <= y1; ++r) {
      if (row_max[r] <= j || !(cells >> ((r / kCellH) * kCellsPerRow) & 0xfu)) continue;
      const float dyf = my - (float(r) + 0.5f);
      const float cdy = 0.5f * c * dyf * dyf, bdy = b * dyf;
      const __m512 pw = _mm512_sub_ps(
          _mm512_xor_ps(_mm512_add_ps(adx2, _mm512_set1_ps(cdy)), _mm512_set1_ps(-0.0f)),
          _mm512_mul_ps(_mm512_set1_ps(bdy), dx));
      const int p0 = r * kTS;
      const __mmask16 ok = _mm512_mask_cmp_ps_mask(
          _mm512_mask_cmplt_epi32_mask(cols, vj, _mm512_load_si512(last + p0)), pw, zero,
          _CMP_LE_OQ);
      if (!ok) continue;
      const __m512 Gv = exp16(pw);
      const __m512 og = _mm512_mul_ps(vo, Gv);
      const __m512 al = _mm512_min_ps(og, _mm512_set1_ps(0.99f));
      const __mmask16 okj =
          _mm512_mask_cmp_ps_mask(ok, al, _mm512_set1_ps(1.0f / 255.0f), _CMP_GE_OQ);
      if (!okj) continue;
      any = true;
      const __m512 om = _mm512_sub_ps(one, al);
      const __m512 Tc = _mm512_load_ps(Tt + p0);
      const __m512 Tj = _mm512_div_ps(Tc, om);
      const __m512 r0 = _mm512_load_ps(R0 + p0), r1 = _mm512_load_ps(R1 + p0),
                   r2 = _mm512_load_ps(R2 + p0);
      const __m512 d0 = _mm512_load_ps(D0 + p0), d1 = _mm512_load_ps(D1 + p0),
                   d2 = _mm512_load_ps(D2 + p0);
      const __m512 dLdal = _mm512_add_ps(
          _mm512_mul_ps(Tj, _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(_mm512_sub_ps(cr, r0), d0),
                                                        _mm512_mul_ps(_mm512_sub_ps(cg, r1), d1)),
                                          _mm512_mul_ps(_mm512_sub_ps(cb, r2), d2))),
          _mm512_div_ps(_mm512_mul_ps(_mm512_load_ps(DA + p0), _mm512_load_ps(Tf + p0)), om));
      const __m512 w = _mm512_maskz_mul_ps(okj, al, Tj);
      s_r = _mm512_add_ps(s_r, _mm512_mul_ps(w, d0));
      s_g = _mm512_add_ps(s_g, _mm512_mul_ps(w, d1));
      s_bl = _mm512_add_ps(s_bl, _mm512_mul_ps(w, d2));
      _mm512_store_ps(R0 + p0,
                      _mm512_mask_add_ps(r0, okj, _mm512_mul_ps(cr, al), _mm512_mul_ps(om, r0)));
      _mm512_store_ps(R1 + p0,
                      _mm512_mask_add_ps(r1, okj, _mm512_mul_ps(cg, al), _mm512_mul_ps(om, r1)));
      _mm512_store_ps(R2 + p0,
                      _mm512_mask_add_ps(r2, okj, _mm512_mul_ps(cb, al), _mm512_mul_ps(om, r2)));
      _mm512_store_ps(Tt + p0, _mm512_mask_mov_ps(Tc, okj, Tj));
      const __mmask16 unclamped =
          _mm512_mask_cmp_ps_mask(okj, og, _mm512_set1_ps(0.99f), _CMP_LE_OQ);
      const __m512 dLdog = _mm512_maskz_mov_ps(unclamped, dLdal);
      s_o = _mm512_add_ps(s_o, _mm512_mul_ps(Gv, dLdog));
      const __m512 dLdpw = _mm512_mul_ps(og, dLdog);
      const __m512 dy = _mm512_set1_ps(dyf);
      s_mx = _mm512_sub_ps(
          s_mx, _mm512_mul_ps(dLdpw, _mm512_add_ps(_mm512_mul_ps(va, dx), _mm512_mul_ps(vb, dy))));
      s_my = _mm512_sub_ps(
          s_my, _mm512_mul_ps(dLdpw, _mm512_add_ps(_mm512_mul_ps(vc, dy), _mm512_mul_ps(vb, dx))));
      s_a = _mm512_sub_ps(
          s_a, _mm512_mul_ps(_mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5f), dx), dx), dLdpw));
      s_c = _mm512_sub_ps(s_c, _mm512_mul_ps(_mm512_set1_ps(0.5f * dyf * dyf), dLdpw));
      s_b = _mm512_sub_ps(s_b, _mm512_mul_ps(_mm512_mul_ps(dx, dy), dLdpw));
    }
    if (!any) continue;
    float* ga = acc + size_t(kNG) * id;
    ga[0] += _mm512_reduce_add_ps(s_mx), ga[1] += _mm512_reduce_add_ps(s_my);
    ga[2] += _mm512_reduce_add_ps(s_a), ga[3] += _mm512_reduce_add_ps(s_b);
    ga[4] += _mm512_reduce_add_ps(s_c), ga[5] += _mm512_reduce_add_ps(s_o);
    ga[6] += _mm512_reduce_add_ps(s_r), ga[7] += _mm512_reduce_add_ps(s_g);
    ga[8] += _mm512_reduce_add_ps(s_bl);
  }
}

#endif

}  // namespace ks::raster
