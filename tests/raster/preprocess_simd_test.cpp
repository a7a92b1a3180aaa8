// The float chain rule in blocks (preprocess_simd.cpp) against the per-Gaussian one
// (preprocess.cpp, whose double instantiation the finite-difference tests check), at both block
// widths, on the screen-space gradients of a real backward pass.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>

#include "raster/raster_internal.hpp"
#include "raster/raster_scene.hpp"

namespace ks {
namespace {

using raster::Isa;

// A scene with every case the chain rule branches on: Gaussians behind the camera and outside
// the image (no gradient), partly outside (the Jacobian clamp), a clamped colour channel, SH of
// the given degree (3K coefficients a multiple of 4 or not: rows moved by transposes or lane by
// lane), and a count that is no multiple of the block widths.
Gaussians chain_rule_scene(int sh_degree) {
  test::SceneOptions o;
  o.n = 45;
  o.sh_degree = sh_degree;
  o.spread = 1.1;
  o.scale_min = 0.02, o.scale_max = 0.25;
  Gaussians g = test::random_scene(o, 17);
  g.means[3 * 4 + 2] = 2.6f;  // behind the camera (it sits at z = 2 looking at the origin)
  g.means[3 * 11] = 40.f, g.means[3 * 13 + 1] = -40.f;  // far outside the image
  const size_t K = size_t(g.coeffs());
  for (int c = 0; c < 3; ++c) g.sh[7 * K * 3 + size_t(c)] = -2.f;  // every channel clamped
  g.sh[9 * K * 3 + 1] = -2.f;                                      // one channel clamped
  // Gaussian 20 in view but behind three large opaque ones on its line of sight from the
  // camera (test_camera, at (0.1, 0.05, 2)): visible, yet it takes no pixel.
  const float at[4][3] = {
      {0.f, 0.f, -0.5f}, {0.04f, 0.02f, 0.5f}, {0.044f, 0.022f, 0.6f}, {0.048f, 0.024f, 0.7f}};
  for (int k = 0; k < 4; ++k) {
    const size_t i = size_t(20 + k);
    for (int c = 0; c < 3; ++c) {
      g.means[3 * i + size_t(c)] = at[k][c];
      g.log_scales[3 * i + size_t(c)] = std::log(k == 0 ? 0.03f : 0.5f);
    }
    if (k > 0) g.opacity_logits[i] = 8.f;
  }
  return g;
}

double rel_rms(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i)
    num += double(a[i] - b[i]) * (a[i] - b[i]), den += double(b[i]) * b[i];
  return std::sqrt(num / std::max(den, 1e-30));
}

class RasterChainRule : public ::testing::TestWithParam<int> {};

TEST_P(RasterChainRule, BlocksAgreeWithThePerGaussianLoop) {
  const Gaussians g = chain_rule_scene(GetParam());
  const size_t K = size_t(g.coeffs());
  const Camera cam = test::test_camera(64, 48);
  RasterResult fwd;
  rasterize_forward(g, cam, {}, fwd);
  size_t culled = 0, clamped = 0;
  for (size_t i = 0; i < g.size(); ++i) culled += fwd.radii[i] == 0;
  for (size_t i = 0; i < g.size(); ++i)  // the render record's clamp bits
    if (fwd.radii[i] > 0) clamped += int(fwd.packed[16 * i + 14]) != 0;
  ASSERT_GT(culled, 2u);
  ASSERT_GT(clamped, 0u);
  Image wc(64, 48, 3), wa(64, 48, 1);
  test::random_upstream(wc, wa, 5);
  RasterGrads gr;
  rasterize_backward(g, cam, {}, fwd, wc, wa, gr);  // fills the screen-space accumulators
  const raster::CameraT<float> c(cam);
  const int threads = omp_get_max_threads();
  // Gaussian 20 is visible and took no pixel: every screen-space sum is zero, so the blocks
  // skip its chain rule and must still write its zero gradients.
  ASSERT_GT(fwd.radii[20], 0);
  for (int th = 0; th < threads; ++th)
    for (int q = 0; q < 9; ++q)
      ASSERT_EQ(gr.scratch[size_t(th) * 9 * g.size() + 9 * 20 + size_t(q)], 0.f);
  RasterGrads ref = gr;
  raster::preprocess_backward(g, c, fwd, threads, ref);
  std::vector<Isa> isas = {Isa::kBaseline};
  if (raster_avx2_available()) isas.push_back(Isa::kAvx2);
  for (Isa isa : isas) {
    RasterGrads b = gr;
    // Stale values everywhere: the blocks must write every entry.
    for (auto* v : {&b.means, &b.log_scales, &b.quats, &b.opacity_logits, &b.sh, &b.means2d})
      std::fill(v->begin(), v->end(), 7.f);
    raster::preprocess_backward_simd(g, c, fwd, threads, isa, b);
    const char* name = isa == Isa::kBaseline ? "blocks of 4" : "blocks of 8";
    EXPECT_LT(rel_rms(b.means, ref.means), 1e-5) << name;
    EXPECT_LT(rel_rms(b.log_scales, ref.log_scales), 1e-5) << name;
    EXPECT_LT(rel_rms(b.quats, ref.quats), 1e-5) << name;
    EXPECT_LT(rel_rms(b.opacity_logits, ref.opacity_logits), 1e-6) << name;
    EXPECT_LT(rel_rms(b.sh, ref.sh), 1e-6) << name;
    EXPECT_EQ(b.means2d, ref.means2d) << name;
    for (size_t i = 0; i < g.size(); ++i) {
      if (fwd.radii[i] != 0) continue;
      EXPECT_EQ(b.means[3 * i], 0.f) << name << " Gaussian " << i;
      EXPECT_EQ(b.quats[4 * i + 1], 0.f) << name << " Gaussian " << i;
      EXPECT_EQ(b.opacity_logits[i], 0.f) << name << " Gaussian " << i;
      EXPECT_EQ(b.sh[i * K * 3 + 2], 0.f) << name << " Gaussian " << i;
    }
  }
  // And the widths agree with each other to rounding in the same order of operations.
  if (isas.size() == 2) {
    RasterGrads b4 = gr, b8 = gr;
    raster::preprocess_backward_simd(g, c, fwd, threads, Isa::kBaseline, b4);
    raster::preprocess_backward_simd(g, c, fwd, threads, Isa::kAvx2, b8);
    EXPECT_EQ(b4.means, b8.means);
    EXPECT_EQ(b4.quats, b8.quats);
    EXPECT_EQ(b4.sh, b8.sh);
  }
}

// The colour's derivatives along the view direction that a full forward stores for SH degree > 0
// (RasterResultT::color_dirs): the chain rule takes the view direction's gradient from them; the
// same gradients to rounding as from the coefficients (a result without them), and at both
// block widths the same stored values.
TEST_P(RasterChainRule, StoredColourDerivativesGiveTheCoefficientsGradient) {
  const Gaussians g = chain_rule_scene(GetParam());
  const Camera cam = test::test_camera(64, 48);
  RasterResult fwd;
  rasterize_forward(g, cam, {}, fwd);
  if (GetParam() == 0) {
    EXPECT_TRUE(fwd.color_dirs.empty());
    return;
  }
  ASSERT_EQ(fwd.color_dirs.size(), 12 * g.size());
  RasterSettings image_only;
  image_only.image_only = true;
  RasterResult io;
  rasterize_forward(g, cam, image_only, io);
  EXPECT_TRUE(io.color_dirs.empty());
  if (raster_avx2_available()) {
    RasterSettings base;
    base.kernel = RasterKernel::kBaseline;
    RasterResult f4;
    rasterize_forward(g, cam, base, f4);
    for (size_t i = 0; i < g.size(); ++i) {
      if (fwd.radii[i] == 0) continue;
      for (int q = 0; q < 12; ++q)
        EXPECT_EQ(f4.color_dirs[12 * i + size_t(q)], fwd.color_dirs[12 * i + size_t(q)]) << i;
    }
  }
  Image wc(64, 48, 3), wa(64, 48, 1);
  test::random_upstream(wc, wa, 5);
  RasterGrads gr;
  rasterize_backward(g, cam, {}, fwd, wc, wa, gr);
  RasterResult without = fwd;
  without.color_dirs.clear();
  const raster::CameraT<float> c(cam);
  const int threads = omp_get_max_threads();
  std::vector<Isa> isas = {Isa::kBaseline};
  if (raster_avx2_available()) isas.push_back(Isa::kAvx2);
  for (Isa isa : isas) {
    RasterGrads a = gr, b = gr;
    raster::preprocess_backward_simd(g, c, fwd, threads, isa, a);
    raster::preprocess_backward_simd(g, c, without, threads, isa, b);
    EXPECT_LT(rel_rms(a.means, b.means), 1e-6);
    // (The direction's part matters here: without the coefficients of degree > 0 it is zero,
    // and the means' gradient moves.)
    Gaussians flat = g;
    for (size_t i = 0; i < flat.size(); ++i)
      for (int f = 3; f < 3 * flat.coeffs(); ++f) flat.sh[i * 3 * size_t(flat.coeffs()) + f] = 0;
    RasterGrads d = gr;
    raster::preprocess_backward_simd(flat, c, without, threads, isa, d);
    EXPECT_GT(rel_rms(d.means, b.means), 1e-3);
    EXPECT_EQ(a.quats, b.quats);
    EXPECT_EQ(a.sh, b.sh);
    EXPECT_EQ(a.log_scales, b.log_scales);
  }
}

INSTANTIATE_TEST_SUITE_P(ShDegrees, RasterChainRule, ::testing::Values(0, 1, 2, 3));

}  // namespace
}  // namespace ks
