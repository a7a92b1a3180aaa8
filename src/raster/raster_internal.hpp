#pragma once
// Pieces shared by the rasterizer's sources (not part of its interface): tile constants, the
// SIMD chunk types, the vectorised exp, kernel selection, phase timing, and the phases each
// source defines (instantiated for float and double).
#include <time.h>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>

#include "core/error.hpp"
#include "raster/projection.hpp"
#include "raster/rasterizer.hpp"

// Vector-extension types wider than the baseline ISA (the double path, the AVX2 kernels) change
// the ABI of internal helpers only; nothing here is exported.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

namespace ks::raster {

// Phase timing on stderr when KS_RASTER_PROFILE is set (diagnostics only).
struct PhaseTimer {
  bool on = std::getenv("KS_RASTER_PROFILE") != nullptr;
  std::chrono::steady_clock::time_point t = std::chrono::steady_clock::now();
  double cpu = cpu_now();
  static double cpu_now() {
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  }
  void mark(const char* name) {
    if (!on) return;
    const auto now = std::chrono::steady_clock::now();
    const double c = cpu_now();
    std::fprintf(stderr, "  %s %.2f ms (master thread CPU %.2f ms)\n", name,
                 std::chrono::duration<double, std::milli>(now - t).count(), c - cpu);
    t = now;
    cpu = c;
  }
};

constexpr int kTS = kTileSize;
constexpr int kRec = 16;        // packed render record per visible Gaussian
constexpr int kColorDirs = 12;  // RasterResultT::color_dirs per Gaussian
constexpr int kNG = 9;  // per-Gaussian screen-space grads: mx, my, a, b, c, opacity, r, g, b
constexpr int kTilePixels = kTS * kTS;
constexpr int kBatch = 64;
// Pixels of a tile row processed together by the baseline kernel (one SIMD vector: SSE2 on the
// portable build, AVX2 when the whole build targets it).
#if defined(__AVX2__)
constexpr int kCW = 8;
#else
constexpr int kCW = 4;
#endif

// The tile kernels these settings run (float; throws for a kernel the CPU lacks).
enum class Isa { kBaseline, kAvx2, kAvx512 };
Isa choose_isa(const RasterSettings& s);

// Explicit SIMD over the CW pixels of a chunk (GCC/Clang vector extensions: SSE2 on the
// baseline build, wider with -march or target("avx2")). The double instantiation (tests) uses
// std::exp per lane. (vector_size must not depend on a template parameter: one explicit
// specialisation a width.)
template <class T, int CW>
struct VecTypes;
template <>
struct VecTypes<float, 4> {
  typedef float V __attribute__((vector_size(16)));
  typedef int32_t I __attribute__((vector_size(16)));
};
template <>
struct VecTypes<float, 8> {
  typedef float V __attribute__((vector_size(32)));
  typedef int32_t I __attribute__((vector_size(32)));
};
template <>
struct VecTypes<double, 4> {
  typedef double V __attribute__((vector_size(32)));
  typedef int64_t I __attribute__((vector_size(32)));
};
template <>
struct VecTypes<double, 8> {
  typedef double V __attribute__((vector_size(64)));
  typedef int64_t I __attribute__((vector_size(64)));
};
// The sign bits of 8 int32 lanes (vmovmskps, as assembly: a generic template cannot call the
// AVX intrinsic, which needs the target in the caller itself; only code inlined into the AVX2
// and AVX-512 kernels instantiates it).
#if defined(__x86_64__)
constexpr bool kHaveSignBits8 = true;
template <class VI>
[[gnu::always_inline]] inline uint32_t sign_bits8(const VI& v) {
  static_assert(sizeof(VI) == 32, "8 lanes of 32 bits");
  uint32_t r;
  asm("vmovmskps %1, %0" : "=r"(r) : "x"(v));
  return r;
}
#else
constexpr bool kHaveSignBits8 = false;
template <class VI>
uint32_t sign_bits8(const VI&) {
  return 0;
}
#endif

// a * b + c lane by lane. In the AVX2 and AVX-512 kernels (8 float lanes, which run only where
// the CPU has FMA: raster_avx2_available) one fused multiply-add, rounded once; elsewhere (the
// SSE2 baseline, double) the product rounded, then the sum. The kernels' forward and backward
// call it at the same places, so that each kernel's backward sees the alphas its forward saw.
// (The builtin, not the intrinsic, which would need the FMA target in this generic function
// itself; only code inlined into the AVX2 and AVX-512 kernels instantiates the fused case.)
template <class V>
[[gnu::always_inline]] inline V madd(const V& a, const V& b, const V& c) {
#if defined(__x86_64__)
  if constexpr (std::is_same_v<V, typename VecTypes<float, 8>::V>)
    return __builtin_ia32_vfmaddps256(a, b, c);
#endif
  return a * b + c;
}

// A scalar in every lane: one vbroadcastss, from memory where s is there, in the AVX2 and
// AVX-512 kernels (8 float lanes, which only they instantiate, as madd); elsewhere s - 0, which
// the compiler folds into a broadcast (V{} + s it cannot: -0 + 0 is +0, so it adds first; and in
// functions compiled for AVX2 by target attribute GCC 12 builds s - 0 lane by lane, with four
// inserts and a 128-bit insert).
template <class V, class T>
[[gnu::always_inline]] inline V splat(const T& s) {
#if defined(__x86_64__)
  if constexpr (std::is_same_v<V, typename VecTypes<float, 8>::V>) {
    V r;
    asm("vbroadcastss %1, %0" : "=v"(r) : "vm"(s));
    return r;
  }
#endif
  return s - V{};
}

template <class T, int CW>
struct Simd;
template <int CW>
struct Simd<float, CW> {
  typedef typename VecTypes<float, CW>::V V;
  typedef typename VecTypes<float, CW>::I I;
  typedef int32_t S;
  // exp for x <= 0 that vectorises (no libm call): Cody-Waite reduction + degree-6 polynomial,
  // relative error ~2e-7.
  [[gnu::always_inline]] static V exp(V x) {
    V out;
    exp_group<1>(&x, &out);
    return out;
  }
  // exp of K vectors, each step for all K before the next: the K dependency chains sit side
  // by side in the instruction stream, so the core overlaps them (one exp is a chain of about
  // 15 dependent operations). exp above is the case K = 1.
  template <int K>
  [[gnu::always_inline]] static void exp_group(const V* x_in, V* out) {
    V x[K], y[K], k[K], r[K], r2[K], r4[K], p[K];
    const V lo = V{} - 87.0f;
    for (int g = 0; g < K; ++g) x[g] = x_in[g] < lo ? lo : x_in[g];
    // y holds round(x / ln 2) in its low mantissa bits (1.5 * 2^23 has a unit last place).
    for (int g = 0; g < K; ++g) y[g] = x[g] * 1.4426950408889634f + 12582912.0f;
    for (int g = 0; g < K; ++g) k[g] = y[g] - 12582912.0f;
    for (int g = 0; g < K; ++g)
      r[g] = (x[g] - k[g] * 0.693145751953125f) - k[g] * 1.428606765330187e-06f;
    for (int g = 0; g < K; ++g) r2[g] = r[g] * r[g];
    for (int g = 0; g < K; ++g) r4[g] = r2[g] * r2[g];
    for (int g = 0; g < K; ++g) {
      const V p01 = r[g] + 1.0f, p23 = r[g] * (1.0f / 6.0f) + 0.5f,
              p45 = r[g] * (1.0f / 120.0f) + 1.0f / 24.0f;
      p[g] = (p01 + r2[g] * p23) + r4[g] * (p45 + r2[g] * (1.0f / 720.0f));
    }
    // 2^k as bits: (k + 127) << 23, from y's bits without a conversion (y's exponent and
    // leading mantissa bits shift out: (bits(y) << 23) == (k << 23)).
    for (int g = 0; g < K; ++g) {
      const I bits = ((I)y[g] << 23) + (127 << 23);
      out[g] = p[g] * (V)bits;
    }
  }
  // 2^x for x <= 0 (the tile kernels' Gaussian falloff, whose exponent comes in base 2:
  // block_power_group): k = round(x), 2^(x - k) by a degree-5 minimax polynomial on
  // [-1/2, 1/2] (relative error 7.5e-8, 2.9e-7 evaluated in float) in Estrin's order, 2^k as
  // bits. Below -126 it gives 2^-126.
  template <int K>
  [[gnu::always_inline]] static void exp2_group(const V* x_in, V* out) {
    V x[K], y[K], r[K], r2[K], r4[K], p[K];
    const V lo = V{} - 126.0f;
    for (int g = 0; g < K; ++g) x[g] = at_least(x_in[g], lo);
    // y holds round(x) + 127 in its low mantissa bits (1.5 * 2^23 + 127 has a unit last
    // place), so that y's bits shifted left by 23 are those of 2^round(x) (the exponent and
    // leading mantissa bits of 1.5 * 2^23 shift out).
    constexpr float kMagic = 12582912.0f + 127.0f;
    for (int g = 0; g < K; ++g) y[g] = x[g] + kMagic;
    for (int g = 0; g < K; ++g) r[g] = x[g] - (y[g] - kMagic);
    for (int g = 0; g < K; ++g) r2[g] = r[g] * r[g];
    for (int g = 0; g < K; ++g) r4[g] = r2[g] * r2[g];
    for (int g = 0; g < K; ++g) {
      const V p01 = madd(r[g], V{} + 0.6931469440460205f, V{} + 1.0000001192092896f),
              p23 = madd(r[g], V{} + 0.05550713092088699f, V{} + 0.24022120237350464f),
              p45 = madd(r[g], V{} + 0.0013276472454890609f, V{} + 0.009675540961325169f);
      p[g] = madd(r4[g], p45, madd(r2[g], p23, p01));
    }
    for (int g = 0; g < K; ++g) out[g] = p[g] * (V)((I)y[g] << 23);
  }
  // a < b ? a : b (minps) or, kMax, a > b ? a : b (maxps), lane by lane: one instruction, which
  // GCC does not make of the vector ternary. Where a lane is NaN (or both are zeros) the
  // instructions give b, the second operand, as the ternaries do: the same bits.
  template <bool kMax>
  [[gnu::always_inline]] static V pick(const V& a, const V& b) {
#if defined(__SSE2__)
    if constexpr (CW == 4)
      return kMax ? (V)_mm_max_ps((__m128)a, (__m128)b) : (V)_mm_min_ps((__m128)a, (__m128)b);
#endif
#if defined(__x86_64__)
    if constexpr (CW == 8) {
      V r;
      if constexpr (kMax)
        asm("vmaxps %2, %1, %0" : "=v"(r) : "v"(a), "vm"(b));
      else
        asm("vminps %2, %1, %0" : "=v"(r) : "v"(a), "vm"(b));
      return r;
    }
#endif
    if constexpr (kMax) return a > b ? a : b;
    return a < b ? a : b;
  }
  // a < b ? a : b.
  [[gnu::always_inline]] static V min(const V& a, const V& b) {
    return pick<false>(a, b);
  }
  // x < lo ? lo : x, i.e. lo > x ? lo : x (a NaN lane of x stays x).
  [[gnu::always_inline]] static V at_least(const V& x, const V& lo) {
    return pick<true>(lo, x);
  }
  // Whether any lane of a comparison mask is set.
  [[gnu::always_inline]] static bool any(const I& m) {
#if defined(__SSE2__)
    if constexpr (CW == 4) return _mm_movemask_ps(_mm_castsi128_ps((__m128i)m)) != 0;
#endif
    if constexpr (CW == 8 && kHaveSignBits8) return sign_bits8(m) != 0;
    for (int l = 0; l < CW; ++l)
      if (m[l]) return true;
    return false;
  }
  // Whether every lane's sign bit is set (every pixel of a block finished).
  [[gnu::always_inline]] static bool all_negative(const V& v) {
#if defined(__SSE2__)
    if constexpr (CW == 4) return _mm_movemask_ps((__m128)v) == 0xf;
#endif
    if constexpr (CW == 8 && kHaveSignBits8) return sign_bits8((I)v) == 0xffu;
    for (int l = 0; l < CW; ++l)
      if (!(v[l] < 0)) return false;
    return true;
  }
};
template <int CW>
struct Simd<double, CW> {
  typedef typename VecTypes<double, CW>::V V;
  typedef typename VecTypes<double, CW>::I I;
  typedef int64_t S;
  static V exp(V x) {
    for (int l = 0; l < CW; ++l) x[l] = std::exp(x[l]);
    return x;
  }
  static V min(const V& a, const V& b) { return a < b ? a : b; }
  template <int K>
  static void exp_group(const V* x, V* out) {
    for (int g = 0; g < K; ++g) out[g] = exp(x[g]);
  }
  template <int K>
  static void exp2_group(const V* x, V* out) {
    for (int g = 0; g < K; ++g)
      for (int l = 0; l < CW; ++l) out[g][l] = std::exp2(x[g][l]);
  }
  static bool any(const I& m) {
    for (int l = 0; l < CW; ++l)
      if (m[l]) return true;
    return false;
  }
  static bool all_negative(const V& v) {
    for (int l = 0; l < CW; ++l)
      if (!(v[l] < 0)) return false;
    return true;
  }
};

template <class V, class T>
[[gnu::always_inline]] inline V vload(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V, class T>
[[gnu::always_inline]] inline void vstore(T* p, const V& v) {
  std::memcpy(p, &v, sizeof v);
}

// Tile-local pixel index of pixel (c, r) when the tile's state is kept in blocks of BW x BH
// pixels, one SIMD vector each (blocks row by row, a block's pixels row by row): lane l of
// block (br, q) is pixel (BW q + l % BW, BH br + l / BW). Blocks of one row are the plain
// row-major layout.
template <int BW, int BH>
constexpr int block_index(int c, int r) {
  return ((r / BH) * (kTS / BW) + c / BW) * (BW * BH) + (r % BH) * BW + c % BW;
}
constexpr int row_index(int c, int r) {
  return block_index<kTS, 1>(c, r);
}
// A Gaussian's conic (a, b, c) as the tile kernels' exponent takes it: in base 2, negated, and
// halved where the quadratic form has 1/2, so that -1/2 d^T Q d / ln 2 = ha d_x^2 + hc d_y^2 +
// hb d_x d_y (Simd::exp2_group then gives exp(-1/2 d^T Q d)).
template <class T>
struct PowerCoeffs {
  T ha, hb, hc;
};
template <class T>
[[gnu::always_inline]] inline PowerCoeffs<T> power_coeffs(T a, T b, T c) {
  constexpr T kLog2e = T(1.4426950408889634);
  return {a * (-kLog2e / 2), b * -kLog2e, c * (-kLog2e / 2)};
}

// A Gaussian's centre coordinate (pixels) made tile-local (tile origin o) less half a pixel, as
// block_power_group takes it: both tile kernels take it from here, so the same bits.
template <class T>
[[gnu::always_inline]] inline T tile_centre(T x, int o) {
  return (x - T(o)) - T(0.5);
}

// K Gaussians over K blocks (all given per Gaussian; cols, rows: the tile-local column and
// row of each lane of the block, block_lanes): each lane's offset from its pixel's centre
// (dx, dy) and the base-2 exponent pw (power_coeffs), from the Gaussian's tile-local centre
// less half a pixel (mx, my). The one expression the forward's and the backward's tile kernels
// use, so that their decisions (alpha >= 1/255, the clamp) agree bit for bit. Each step is done
// for all K before the next, so that the K dependency chains overlap.
template <int K, class V, class T>
[[gnu::always_inline]] inline void block_power_group(const T* mx, const T* my, const T* ha,
                                                     const T* hb, const T* hc, const V* cols,
                                                     const V* rows, V* dx, V* dy, V* pw) {
  for (int g = 0; g < K; ++g) dx[g] = mx[g] - cols[g];
  for (int g = 0; g < K; ++g) dy[g] = my[g] - rows[g];
  // (ha dx + hb dy) dx + hc dy dy: five operations.
  V t[K];
  for (int g = 0; g < K; ++g) t[g] = madd(splat<V>(hb[g]), dy[g], ha[g] * dx[g]);
  for (int g = 0; g < K; ++g) pw[g] = t[g] * dx[g];
  for (int g = 0; g < K; ++g) pw[g] = madd(hc[g] * dy[g], dy[g], pw[g]);
}

// A visible Gaussian's tiles (RasterResultT::tile_rects) as two words, tx0 | tx1 << 16 and
// ty0 | ty1 << 16, from its inclusive pixel rectangle; and back.
inline uint32_t pack_tile_span(int p0, int p1) {
  return uint32_t(p0 / kTS) | uint32_t(p1 / kTS) << 16;
}
struct TileRect {
  int tx0, tx1, ty0, ty1;
};
inline TileRect unpack_tile_rect(uint32_t xr, uint32_t yr) {
  return {int(xr & 0xffff), int(xr >> 16), int(yr & 0xffff), int(yr >> 16)};
}

// The blocks of block rows br0..br1 and block columns q0..q1 as bits (block br * kTS / BW + q),
// for tiles of at most 64 blocks: the tile kernels skip a Gaussian whose box holds none of the
// blocks still to be done.
template <int BW, int BH>
constexpr uint64_t box_blocks(int q0, int q1, int br0, int br1) {
  constexpr int kBPR = kTS / BW;
  static_assert(kTilePixels / (BW * BH) <= 64, "one bit a block");
  constexpr uint64_t kRowFirst = [] {
    uint64_t m = 0;
    for (int br = 0; br < kTilePixels / (BW * BH) / kBPR; ++br) m |= uint64_t(1) << (br * kBPR);
    return m;
  }();
  const uint64_t rows_in = kRowFirst & (~uint64_t(0) >> (63 - ((br1 + 1) * kBPR - 1))) &
                           ~((uint64_t(1) << (br0 * kBPR)) - 1);
  const uint64_t cols_in = (uint64_t(2) << q1) - (uint64_t(1) << q0);
  return rows_in * cols_in;  // each row's first-column bit spread over the columns
}

// The blocks of a tile (origin ox, oy) that a render record's pixel box (rec[10..13]: x0, x1,
// y0, y1, whole pixels within the image) covers, as box_blocks gives them: the box made
// tile-local and clamped to the tile four coordinates at a time, its block rows and columns
// looked up. Only for entries of that tile (their box meets it).
template <int BW, int BH, class T>
[[gnu::always_inline]] inline uint64_t entry_blocks(const T* rec, int ox, int oy) {
  constexpr int kBPR = kTS / BW, kRows = kTS / BH;
  static_assert((BW & (BW - 1)) == 0 && (BH & (BH - 1)) == 0, "powers of two");
  struct Tables {
    uint64_t cols[kBPR * kBPR], rows[kRows * kRows];
  };
  static constexpr Tables kTab = [] {
    Tables t{};
    for (int a = 0; a < kBPR; ++a)
      for (int b = a; b < kBPR; ++b) t.cols[a * kBPR + b] = box_blocks<BW, BH>(a, b, 0, kRows - 1);
    for (int a = 0; a < kRows; ++a)
      for (int b = a; b < kRows; ++b) t.rows[a * kRows + b] = box_blocks<BW, BH>(0, kBPR - 1, a, b);
    return t;
  }();
  typedef int32_t I4 __attribute__((vector_size(16)));
  I4 b;
  if constexpr (std::is_same_v<T, float>) {
    typedef float F4 __attribute__((vector_size(16)));
    b = __builtin_convertvector(vload<F4>(rec + 10), I4);
  } else {
    b = I4{int(rec[10]), int(rec[11]), int(rec[12]), int(rec[13])};
  }
  b -= I4{ox, ox, oy, oy};
  b = b < 0 ? I4{} : b;
  b = b > kTS - 1 ? I4{} + (kTS - 1) : b;
  const uint32_t q0 = uint32_t(b[0]) / BW, q1 = uint32_t(b[1]) / BW;
  const uint32_t r0 = uint32_t(b[2]) / BH, r1 = uint32_t(b[3]) / BH;
  return kTab.cols[q0 * kBPR + q1] & kTab.rows[r0 * kRows + r1];
}

// The forward's record for the backward of where each (tile, Gaussian) entry contributed
// (RasterResultT::entry_cells): a tile's 32 cells of 4 x 2 pixels, cell (r / 2) * 4 + c / 4 of
// pixel (c, r), as bits, whatever block shape a kernel uses. block_cells: the cells a block of
// BW x BH pixels (number br * kTS / BW + q) overlaps; cells_blocks: the blocks that overlap a
// set of cells. For the AVX2 kernels' 4 x 2 blocks, cells are blocks.
constexpr int kCellW = 4, kCellH = 2, kCellsPerRow = kTS / kCellW;
static_assert(kTilePixels / (kCellW * kCellH) == 32, "one bit a cell in 32 bits");
template <int BW, int BH>
constexpr uint32_t block_cells(int blk) {
  constexpr int kBPR = kTS / BW;
  const int c0 = (blk % kBPR) * BW, r0 = (blk / kBPR) * BH;
  uint32_t m = 0;
  for (int r = r0; r < r0 + BH; r += std::min(BH, kCellH))
    for (int c = c0; c < c0 + BW; c += std::min(BW, kCellW))
      m |= uint32_t(1) << ((r / kCellH) * kCellsPerRow + c / kCellW);
  return m;
}
// The cells of block blk's lanes that are set in m (lane l: column l % BW, row l / BW of the
// block), for a block larger than a cell (the baseline kernel's 8 x 1 blocks where it is built
// for 8 lanes), which may have contributed in one of its cells only.
template <int BW, int BH, class VI>
inline uint32_t lanes_cells(int blk, const VI& m) {
  constexpr int kBPR = kTS / BW;
  const int c0 = (blk % kBPR) * BW, r0 = (blk / kBPR) * BH;
  uint32_t cells = 0;
  for (int l = 0; l < BW * BH; ++l)
    if (m[l])
      cells |= uint32_t(1) << (((r0 + l / BW) / kCellH) * kCellsPerRow + (c0 + l % BW) / kCellW);
  return cells;
}
template <int BW, int BH>
[[gnu::always_inline]] inline uint64_t cells_blocks(uint32_t cells) {
  if constexpr (BW == kCellW && BH == kCellH) {
    return cells;
  } else {
    constexpr int kBlocks = kTilePixels / (BW * BH);
    static_assert(kBlocks <= 64, "one bit a block");
    uint64_t m = 0;
    for (int blk = 0; blk < kBlocks; ++blk)
      m |= uint64_t((block_cells<BW, BH>(blk) & cells) != 0) << blk;
    return m;
  }
}

// The tile-local column and row of each lane of block blk (br * kTS / BW + q), from each lane's
// column and row within its block (block_columns, block_rows): exact small integers.
template <int BW, int BH, class V>
[[gnu::always_inline]] inline void block_lanes(int blk, const V& col_off, const V& row_off, V& cols,
                                               V& rows) {
  using T = std::remove_reference_t<decltype(col_off[0])>;
  constexpr int kBPR = kTS / BW;
  cols = col_off + T((blk % kBPR) * BW), rows = row_off + T((blk / kBPR) * BH);
}
// Each lane's column (l % BW) and row (l / BW) within its block.
template <class V, int BW, int BH>
[[gnu::always_inline]] inline V block_columns() {
  V v{};
  for (int l = 0; l < BW * BH; ++l) v[l] = l % BW;
  return v;
}
template <class V, int BW, int BH>
[[gnu::always_inline]] inline V block_rows() {
  V v{};
  for (int l = 0; l < BW * BH; ++l) v[l] = l / BW;
  return v;
}

// Whether a tile-local layout keeps each row's pixels 4c .. 4c + 3 side by side (store_tile
// moves them four at a time).
template <int (*index)(int, int)>
constexpr bool fours_side_by_side() {
  for (int r = 0; r < kTS; ++r)
    for (int c = 0; c < kTS; ++c)
      if (index(c, r) != index(c & ~3, r) + (c & 3)) return false;
  return true;
}

// A finished tile's pixels from its tile-local state (kTilePixels each, pixel (c, r) at
// index(c, r)) into `out`: colour over the background by the final transmittance |Tt|, alpha,
// with `full` the backward's state (final transmittance, last contributor) and with `depth` the
// expected depth. Four pixels of a row at a time where the image holds them (the colours
// interleaved by shuffles), the same operations on each pixel as one at a time.
template <class T, class S, int (*index)(int, int) = row_index>
[[gnu::always_inline]] inline void store_tile(RasterResultT<T>& out, int ox, int oy, const T* bg,
                                              const T* Tt, const T* C0, const T* C1, const T* C2,
                                              const T* Dp, const S* last, bool full, bool depth) {
  static_assert(fours_side_by_side<index>(), "rows of four pixels side by side");
  static_assert(sizeof(S) == sizeof(T), "S: the integer of T's width");
  typedef T V4 __attribute__((vector_size(4 * sizeof(T))));
  typedef S I4 __attribute__((vector_size(4 * sizeof(S))));
  const I4 no_sign = I4{} + std::numeric_limits<S>::max();
  const int W = out.color.width, H = out.color.height;
  const int w = std::min(kTS, W - ox);
  for (int r = 0; r < kTS && oy + r < H; ++r) {
    const size_t row = size_t(oy + r) * W + ox;
    int c = 0;
    for (; c + 4 <= w; c += 4) {
      const int p = index(c, r);
      const size_t pix = row + size_t(c);
      const V4 Tf = (V4)((I4)vload<V4>(Tt + p) & no_sign);
      const V4 r0 = vload<V4>(C0 + p) + Tf * bg[0], r1 = vload<V4>(C1 + p) + Tf * bg[1],
               r2 = vload<V4>(C2 + p) + Tf * bg[2];
      const V4 t0 = __builtin_shufflevector(r0, r1, 0, 4, 1, 5);
      const V4 t1 = __builtin_shufflevector(r1, r2, 1, 5, 2, 6);
      const V4 t2 = __builtin_shufflevector(r0, r1, 3, 7, 3, 7);
      T* rgb = &out.color.data[3 * pix];
      vstore(rgb, __builtin_shufflevector(t0, r2, 0, 1, 4, 2));
      vstore(rgb + 4, __builtin_shufflevector(t1, r0, 0, 1, 6, 2));
      vstore(rgb + 8, __builtin_shufflevector(r2, t2, 2, 4, 5, 3));
      vstore(&out.alpha.data[pix], T(1) - Tf);
      if (depth) vstore(&out.depth.data[pix], vload<V4>(Dp + p));
      if (full) {
        vstore(&out.final_T[pix], Tf);
        const auto n =
            __builtin_convertvector(vload<I4>(last + p), uint32_t __attribute__((vector_size(16))));
        vstore(&out.n_contrib[pix], n);
      }
    }
    for (; c < w; ++c) {
      const int p = index(c, r);
      const size_t pix = row + size_t(c);
      const T Tf = std::abs(Tt[p]);
      out.color.data[3 * pix] = C0[p] + Tf * bg[0];
      out.color.data[3 * pix + 1] = C1[p] + Tf * bg[1];
      out.color.data[3 * pix + 2] = C2[p] + Tf * bg[2];
      out.alpha.data[pix] = 1 - Tf;
      if (depth) out.depth.data[pix] = Dp[p];
      if (full) {
        out.final_T[pix] = Tf;
        out.n_contrib[pix] = uint32_t(last[p]);
      }
    }
  }
}

template <class T>
void check_gaussians(const GaussiansT<T>& g) {
  const size_t n = g.size();
  const size_t K = size_t(g.coeffs());
  if (g.sh_degree < 0 || g.sh_degree > 3)
    throw Error("rasterizer: SH degree " + std::to_string(g.sh_degree) + " not in 0..3");
  if (g.means.size() != 3 * n || g.log_scales.size() != 3 * n || g.quats.size() != 4 * n ||
      g.sh.size() != n * K * 3)
    throw Error("rasterizer: inconsistent Gaussian array sizes");
}

// The parameter gradients of N Gaussians with K SH coefficients a channel, sized (not zeroed).
template <class T>
void size_param_grads(RasterGradsT<T>& gr, size_t N, int K) {
  gr.means.resize(3 * N);
  gr.log_scales.resize(3 * N);
  gr.quats.resize(4 * N);
  gr.opacity_logits.resize(N);
  gr.sh.resize(N * size_t(K) * 3);
  gr.means2d.resize(2 * N);
}

// ---- The phases (each defined in its own source, instantiated for float and double).

// preprocess.cpp: project every Gaussian (culling, screen footprint, colour) into `out`, one at a
// time with the projection.hpp pairs (instantiated for double: float takes the block version).
template <class T>
void preprocess_forward(const GaussiansT<T>& g, const CameraT<T>& cam, const RasterSettings& s,
                        RasterResultT<T>& out);
// preprocess.cpp: the chain rule per Gaussian from the summed screen-space gradients
// (kNG per Gaussian in gr.scratch, per thread) to the raw parameters.
template <class T>
void preprocess_backward(const GaussiansT<T>& g, const CameraT<T>& cam, const RasterResultT<T>& fwd,
                         int threads, RasterGradsT<T>& gr);
// preprocess_simd.cpp: the same projection for float, blocks of 4 (SSE2) or 8 (AVX2) Gaussians.
void preprocess_forward_simd(const GaussiansT<float>& g, const CameraT<float>& cam,
                             const RasterSettings& s, Isa isa, RasterResultT<float>& out,
                             const GaussianSource* source = nullptr);
// preprocess_simd.cpp: the chain rule of preprocess_backward for float in the same blocks.
void preprocess_backward_simd(const GaussiansT<float>& g, const CameraT<float>& cam,
                              const RasterResultT<float>& fwd, int threads, Isa isa,
                              RasterGradsT<float>& gr);
// binning.cpp: depth order of the visible Gaussians, their render records, per-tile lists.
template <class T>
void sort_and_bin(RasterResultT<T>& out, int tiles_x, int tiles_y);
// tiles_forward.cpp: front-to-back compositing of every tile.
template <class T>
void composite_tiles(RasterResultT<T>& out, int tiles_x, int tiles_y, const T* bg, Isa isa);
// tiles_backward.cpp: every tile in reverse order, screen-space gradients into per-thread
// accumulators (kNG per Gaussian, `threads` buffers in gr.scratch).
template <class T>
void backward_tiles(const RasterResultT<T>& fwd, const ImageT<T>& dLdc, const ImageT<T>& dLda,
                    const T* bg, int tiles_x, int tiles_y, Isa isa, int threads,
                    RasterGradsT<T>& gr);

}  // namespace ks::raster

#pragma GCC diagnostic pop
