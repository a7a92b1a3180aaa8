// The tile kernels' shared numeric pieces (src/raster/raster_internal.hpp): the base-2
// exponential, the exponent from a conic, the minimum, the multiply-add, and an entry's blocks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "raster/raster_internal.hpp"
#include "raster/rasterizer.hpp"

namespace ks::raster {
namespace {

using SV = Simd<float, 4>;
using V = SV::V;

TEST(RasterInternal, Exp2IsWithinItsErrorOverTheKernelsRange) {
  double worst = 0;
  // Down to -100 (alpha >= 1/255 needs about -8; near -126 the results are subnormal floats).
  for (int i = 0; i <= 100 * 4096; i += 4) {
    V x, out;
    for (int l = 0; l < 4; ++l) x[l] = -float(i + l) / 4096.f;
    SV::exp2_group<1>(&x, &out);
    for (int l = 0; l < 4; ++l) {
      const double ref = std::exp2(double(x[l]));
      worst = std::max(worst, std::abs(double(out[l]) - ref) / ref);
    }
  }
  EXPECT_LT(worst, 3.5e-7);
  // Below -126 (far outside a Gaussian's box, where alpha < 1/255 anyway): 2^-126, never an
  // infinity or a NaN.
  V x = {-126.5f, -1000.f, -1e30f, -std::numeric_limits<float>::infinity()}, out;
  SV::exp2_group<1>(&x, &out);
  for (int l = 0; l < 4; ++l) EXPECT_NEAR(out[l], std::exp2(-126.f), 1e-6 * std::exp2(-126.f));
  // The double path is std::exp2.
  using SD = Simd<double, 4>;
  SD::V xd = {-0.3, -1.7, -20.25, 0}, od;
  SD::exp2_group<1>(&xd, &od);
  for (int l = 0; l < 4; ++l) EXPECT_EQ(od[l], std::exp2(xd[l]));
}

TEST(RasterInternal, PowerFromTheConicIsTheFalloffInBaseTwo) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (int trial = 0; trial < 200; ++trial) {
    // A positive definite conic and a block of lanes around its centre.
    const float a = 0.05f + std::abs(u(rng)), c = 0.05f + std::abs(u(rng));
    const float b = 0.9f * u(rng) * std::sqrt(a * c);
    const PowerCoeffs<float> pc = power_coeffs(a, b, c);
    const float mx = 6.f * u(rng), my = 6.f * u(rng);
    V cols = {0, 1, 2, 3}, rows = {1, 1, 2, 2}, dx, dy, pw, g;
    block_power_group<1>(&mx, &my, &pc.ha, &pc.hb, &pc.hc, &cols, &rows, &dx, &dy, &pw);
    SV::exp2_group<1>(&pw, &g);
    for (int l = 0; l < 4; ++l) {
      const double ex = double(mx) - cols[l], ey = double(my) - rows[l];
      EXPECT_FLOAT_EQ(dx[l], float(ex));
      EXPECT_FLOAT_EQ(dy[l], float(ey));
      const double power = -0.5 * (a * ex * ex + c * ey * ey) - b * ex * ey;
      EXPECT_LE(pw[l], 0.f);
      EXPECT_NEAR(pw[l] * std::log(2.0), power, 1e-5 * (1 + std::abs(power)));
      EXPECT_NEAR(g[l], std::exp2(double(pw[l])), 3.5e-7 * std::exp2(double(pw[l])));
      // Where alpha can reach 1/255 (power > -ln 255), within the float exponent's rounding.
      if (power > -6) {
        EXPECT_NEAR(g[l], std::exp(power), 4e-6 * std::exp(power));
      }
    }
  }
}

TEST(RasterInternal, MinIsTheTernaryBitForBit) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const V a = {0.5f, 2.f, nan, -0.f}, b = {0.99f, 0.99f, 0.99f, 0.f};
  const V m = SV::min(a, b);
  const V t = a < b ? a : b;
  for (int l = 0; l < 4; ++l) EXPECT_EQ(std::memcmp(&m[l], &t[l], 4), 0) << l;
}

TEST(RasterInternal, AtLeastIsTheTernaryBitForBit) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const V x = {-200.f, 3.f, nan, -0.f}, lo = {-126.f, -126.f, -126.f, 0.f};
  const V m = SV::at_least(x, lo);
  const V t = x < lo ? lo : x;
  for (int l = 0; l < 4; ++l) EXPECT_EQ(std::memcmp(&m[l], &t[l], 4), 0) << l;
}

template <int BW, int BH>
void expect_entry_blocks_match_the_box() {
  // Every pixel box that meets tile (1, 2) of a 64 x 64 image, clipped to the image as the
  // records are, against box_blocks of its tile-local clamped block range.
  const int ox = 16, oy = 32;
  for (int x0 = 0; x0 < 40; x0 += 3)
    for (int x1 = std::max(x0, ox); x1 < 64; x1 += 5)
      for (int y0 = 0; y0 < 56; y0 += 5)
        for (int y1 = std::max(y0, oy); y1 < 64; y1 += 3) {
          if (x0 > ox + kTS - 1 || y0 > oy + kTS - 1) continue;
          float rec[kRec] = {};
          rec[10] = float(x0), rec[11] = float(x1), rec[12] = float(y0), rec[13] = float(y1);
          const int q0 = std::max(x0 - ox, 0) / BW, q1 = std::min(x1 - ox, kTS - 1) / BW;
          const int r0 = std::max(y0 - oy, 0) / BH, r1 = std::min(y1 - oy, kTS - 1) / BH;
          EXPECT_EQ((entry_blocks<BW, BH>(rec, ox, oy)), (box_blocks<BW, BH>(q0, q1, r0, r1)))
              << x0 << " " << x1 << " " << y0 << " " << y1;
          double drec[kRec] = {};
          for (int k = 10; k < 14; ++k) drec[k] = rec[k];
          EXPECT_EQ((entry_blocks<BW, BH>(drec, ox, oy)), (box_blocks<BW, BH>(q0, q1, r0, r1)));
        }
}

using V8 = VecTypes<float, 8>::V;
// madd on 8 lanes as the AVX2 and AVX-512 kernels compile it (inlined into a function with the
// FMA target; the lanes through memory, since an AVX vector argument changes the calling
// convention between this file's baseline code and that function).
__attribute__((target("avx2,fma"), noinline)) void madd8(const float* a, const float* b,
                                                         const float* c, float* out) {
  V8 va, vb, vc;
  std::memcpy(&va, a, sizeof va), std::memcpy(&vb, b, sizeof vb), std::memcpy(&vc, c, sizeof vc);
  const V8 r = madd(va, vb, vc);
  std::memcpy(out, &r, sizeof r);
}

// One rounding on the wider kernels' 8 lanes (std::fma), two on the baseline's 4 (the product,
// then the sum), lane for lane; operands where the two differ.
TEST(RasterInternal, MaddFusesOnEightLanesOnly) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-2.f, 2.f);
  int differ = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    float a[8], b[8], c[8], r8[8];
    for (int l = 0; l < 8; ++l) a[l] = u(rng), b[l] = u(rng), c[l] = u(rng);
    V a4, b4, c4;
    for (int l = 0; l < 4; ++l) a4[l] = a[l], b4[l] = b[l], c4[l] = c[l];
    const V r4 = madd(a4, b4, c4);
    for (int l = 0; l < 4; ++l) {
      const float p = a4[l] * b4[l];
      EXPECT_EQ(r4[l], p + c4[l]);
      differ += r4[l] != std::fma(a4[l], b4[l], c4[l]);
    }
    if (!raster_avx2_available()) continue;
    madd8(a, b, c, r8);
    for (int l = 0; l < 8; ++l) EXPECT_EQ(r8[l], std::fma(a[l], b[l], c[l]));
  }
  EXPECT_GT(differ, 0);
}

// splat on 8 lanes as the AVX2 and AVX-512 kernels compile it: from memory and from a register.
__attribute__((target("avx2,fma"), noinline)) void splat8(const float* s, float* from_memory,
                                                          float* from_register) {
  const V8 m = splat<V8>(s[0]);
  const float t = s[0] * s[1];
  const V8 r = splat<V8>(t);
  std::memcpy(from_memory, &m, sizeof m), std::memcpy(from_register, &r, sizeof r);
}

// The scalar in every lane, bit for bit (-0 and NaN too), on 4 lanes and on 8.
TEST(RasterInternal, SplatPutsTheScalarInEveryLane) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const float x : {1.5f, -0.f, 0.f, -3e-39f, nan}) {
    const V v = splat<V>(x);
    for (int l = 0; l < 4; ++l) EXPECT_EQ(std::memcmp(&v[l], &x, 4), 0) << x << " lane " << l;
    if (!raster_avx2_available()) continue;
    const float s[2] = {x, 1.f};
    float m[8], r[8];
    splat8(s, m, r);
    for (int l = 0; l < 8; ++l) {
      EXPECT_EQ(std::memcmp(&m[l], &x, 4), 0) << x << " lane " << l;
      EXPECT_EQ(std::memcmp(&r[l], &x, 4), 0) << x << " lane " << l;
    }
  }
}

TEST(RasterInternal, EntryBlocksAreTheBoxsBlocks) {
  expect_entry_blocks_match_the_box<4, 2>();
  expect_entry_blocks_match_the_box<4, 1>();
  expect_entry_blocks_match_the_box<8, 1>();
}

}  // namespace
}  // namespace ks::raster
