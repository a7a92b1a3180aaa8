// The decoders' first layer in texel space (reconstruct/texel_layer0.hpp) against the point-wise
// first layer it replaces: the same Gaussians and parameter gradients up to float rounding, for
// the two MLPs and the joint one; the same bits on one thread and two; and its refusals. (The
// finite-difference test of the whole decoder, decoder_test.cpp, runs it too, with 8 channels.)
#include "reconstruct/texel_layer0.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "reconstruct/decoder.hpp"
#include "reconstruct/decoder_fixture.hpp"
#include "reconstruct/mlp_kernels.hpp"

namespace ks {
namespace {

using test::DecoderFixture;
using test::Upstream;

struct PathGuard {
  explicit PathGuard(TexelLayer0::Path p) { TexelLayer0::set_path(p); }
  ~PathGuard() { TexelLayer0::set_path(TexelLayer0::Path::kAuto); }
};

// One decode and backward: the decoded Gaussians and offsets, then every group's gradient.
struct Outcome {
  Gaussians g;
  std::vector<float> offsets;
  std::vector<std::string> names;
  std::vector<std::vector<float>> grads;
};

DecoderOptions options(bool joint) {
  DecoderOptions o = DecoderFixture().o;
  o.triplane_res = 16;
  o.triplane_channels = 8;
  o.hidden = 16;
  o.joint = joint;
  o.max_offset = 0.2f;
  return o;
}

// times: decodes and backwards in a row (the parameters unchanged), the last one's outcome.
Outcome run(const DecoderFixture& f, const DecoderOptions& o, TexelLayer0::Path path,
            int times = 1) {
  PathGuard guard(path);
  const float sh0[3] = {0.1f, 0.2f, 0.3f};
  Decoder d;
  d.init(o, 5, f.anchors, f.faces, 0.f, sh0);
  Adam adam;
  d.add_parameters(adam, OptimizerOptions{});
  // Larger weights than the init's, so that every output and gradient is far from zero.
  for (const AdamGroup& g : adam.groups())
    if (g.name != "triplane")
      for (float& v : *adam.group(g.name).params) v *= 3.f;
  Outcome r;
  const int n = int(f.anchors.rows());
  const Upstream u(n, 11);
  for (int k = 0; k < times; ++k) {
    d.decode(f.anchors, f.xs, f.ys, f.zs, f.bias, r.g, r.offsets);
    d.backward(f.xs, f.ys, f.zs, u.dm, u.doff, u.dls, u.dq, u.dop, u.dsh);
  }
  for (const AdamGroup& g : adam.groups()) {
    r.names.push_back(g.name);
    r.grads.push_back(*g.grads);
  }
  return r;
}

bool available(const DecoderOptions& o) {
  Triplane tp;
  const float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
  tp.init(o.triplane_res, o.triplane_channels, lo, hi, 1);
  Mlp m;
  m.init({tp.feature_dim(), o.hidden, o.hidden, 9}, 1);
  const Mlp* mlps[1] = {&m};
  return TexelLayer0::available(tp, mlps, 1);
}

void expect_close(const std::vector<float>& a, const std::vector<float>& b, double tol,
                  const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  double scale = 0;
  for (float v : b) scale = std::max(scale, double(std::abs(v)));
  EXPECT_GT(scale, 0) << what;
  for (size_t k = 0; k < a.size(); ++k)
    ASSERT_NEAR(a[k], b[k], tol * std::max(1.0, scale)) << what << " " << k;
}

TEST(TexelLayer0, DecoderMatchesThePointWiseFirstLayer) {
  const DecoderFixture f;
  for (const bool joint : {false, true}) {
    const DecoderOptions o = options(joint);
    if (!available(o)) GTEST_SKIP() << "no AVX2/FMA: the texel-space path is not taken";
    const Outcome t = run(f, o, TexelLayer0::Path::kAuto);
    const Outcome p = run(f, o, TexelLayer0::Path::kPoints);
    const std::string j = joint ? "joint " : "split ";
    expect_close(t.g.means, p.g.means, 1e-5, j + "means");
    expect_close(t.g.log_scales, p.g.log_scales, 1e-5, j + "log_scales");
    expect_close(t.g.quats, p.g.quats, 1e-5, j + "quats");
    expect_close(t.g.opacity_logits, p.g.opacity_logits, 1e-5, j + "opacity");
    expect_close(t.g.sh, p.g.sh, 1e-5, j + "sh");
    expect_close(t.offsets, p.offsets, 1e-5, j + "offsets");
    ASSERT_EQ(t.names, p.names);
    for (size_t k = 0; k < t.names.size(); ++k)
      expect_close(t.grads[k], p.grads[k], 1e-5, j + t.names[k]);
  }
}

TEST(TexelLayer0, SameBitsOnOneThreadAndTwo) {
  const DecoderFixture f;
  const DecoderOptions o = options(false);
  if (!available(o)) GTEST_SKIP() << "no AVX2/FMA: the texel-space path is not taken";
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const Outcome one = run(f, o, TexelLayer0::Path::kAuto);
  omp_set_num_threads(2);
  const Outcome two = run(f, o, TexelLayer0::Path::kAuto);
  omp_set_num_threads(threads);
  EXPECT_EQ(one.g.means, two.g.means);
  EXPECT_EQ(one.g.sh, two.g.sh);
  for (size_t k = 0; k < one.grads.size(); ++k) EXPECT_EQ(one.grads[k], two.grads[k]) << k;
}

// The MLP kernels' two widths (mlp_kernels.hpp; the texel layer's blend and gather follow their
// choice) give the same bits through the texel layer.
TEST(TexelLayer0, Avx512KernelsGiveTheAvx2Bits) {
  const DecoderFixture f;
  const DecoderOptions o = options(false);
  if (!available(o)) GTEST_SKIP() << "no AVX2/FMA: the texel-space path is not taken";
  if (!mlp_kernels::cpu_has_avx512()) GTEST_SKIP() << "CPU has no AVX-512";
  mlp_kernels::set_path(mlp_kernels::Path::kAvx2);
  const Outcome a = run(f, o, TexelLayer0::Path::kAuto);
  mlp_kernels::set_path(mlp_kernels::Path::kAvx512);
  const Outcome b = run(f, o, TexelLayer0::Path::kAuto);
  mlp_kernels::set_path(mlp_kernels::Path::kAuto);
  EXPECT_EQ(a.g.means, b.g.means);
  EXPECT_EQ(a.g.sh, b.g.sh);
  EXPECT_EQ(a.offsets, b.offsets);
  for (size_t k = 0; k < a.grads.size(); ++k) EXPECT_EQ(a.grads[k], b.grads[k]) << a.names[k];
}

// The backward leaves its texel gradients zeroed for the next one: a second step of the same
// parameters gives the same bits.
TEST(TexelLayer0, SecondStepGivesTheSameBits) {
  const DecoderFixture f;
  const DecoderOptions o = options(false);
  if (!available(o)) GTEST_SKIP() << "no AVX2/FMA: the texel-space path is not taken";
  const Outcome once = run(f, o, TexelLayer0::Path::kAuto);
  const Outcome twice = run(f, o, TexelLayer0::Path::kAuto, 2);
  EXPECT_EQ(once.g.means, twice.g.means);
  for (size_t k = 0; k < once.grads.size(); ++k) EXPECT_EQ(once.grads[k], twice.grads[k]) << k;
}

// Anchors that move (density control) between decodes: the second decode reads the new points'
// texels, as a decoder that only ever saw them does.
TEST(TexelLayer0, NewPointsAreTakenUp) {
  const DecoderFixture f;
  const DecoderOptions o = options(false);
  if (!available(o)) GTEST_SKIP() << "no AVX2/FMA: the texel-space path is not taken";
  DecoderFixture moved = f;
  for (size_t i = 0; i < moved.xs.size(); ++i) {
    moved.anchors(long(i), 0) += 0.03, moved.anchors(long(i), 1) -= 0.02;
    moved.xs[i] = float(moved.anchors(long(i), 0)), moved.ys[i] = float(moved.anchors(long(i), 1));
  }
  const float sh0[3] = {0.1f, 0.2f, 0.3f};
  Decoder both, fresh;
  both.init(o, 5, f.anchors, f.faces, 0.f, sh0);
  fresh.init(o, 5, f.anchors, f.faces, 0.f, sh0);
  Gaussians g, h;
  std::vector<float> off, off2;
  both.decode(f.anchors, f.xs, f.ys, f.zs, f.bias, g, off);
  both.decode(moved.anchors, moved.xs, moved.ys, moved.zs, moved.bias, g, off);
  fresh.decode(moved.anchors, moved.xs, moved.ys, moved.zs, moved.bias, h, off2);
  EXPECT_EQ(g.means, h.means);
  EXPECT_EQ(g.sh, h.sh);
}

TEST(TexelLayer0, RefusesWhatItCannotServe) {
  Triplane tp;
  const float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
  tp.init(8, 8, lo, hi, 1);
  Mlp m;
  m.init({tp.feature_dim(), 8, 8, 3}, 1);
  const Mlp* mlps[1] = {&m};
  TexelLayer0 t;
  MlpCache cache;
  Mlp::Mat Y;
  mlp_tail_buffers(m, 2, cache, Y);
  MlpCache* caches[1] = {&cache};
  if (TexelLayer0::available(tp, mlps, 1)) {
    // Nothing to read yet.
    EXPECT_THROW(t.forward(tp, mlps, 1, caches), Error);
  }
  const float xs[2] = {0.f, 0.5f}, ys[2] = {0.f, -0.5f}, zs[2] = {0.f, 0.25f};
  // Marks of another plane size, and marks that miss a texel the points read.
  EXPECT_THROW(t.set_points(tp, std::vector<uint8_t>(10, 1), xs, ys, zs, 2), Error);
  std::vector<uint8_t> marked;
  triplane_mark_texels(tp, xs, ys, zs, 1, &marked);  // the first point's texels only
  EXPECT_THROW(t.set_points(tp, marked, xs, ys, zs, 2), Error);
  triplane_mark_texels(tp, xs, ys, zs, 2, &marked);
  EXPECT_NO_THROW(t.set_points(tp, marked, xs, ys, zs, 2));
  // Widths that are not a multiple of 8, and a one-layer MLP, go the point-wise way.
  Mlp odd;
  odd.init({tp.feature_dim(), 12, 12, 3}, 1);
  const Mlp* odds[1] = {&odd};
  EXPECT_FALSE(TexelLayer0::available(tp, odds, 1));
  Mlp one;
  one.init({tp.feature_dim(), 8}, 1);
  const Mlp* ones[1] = {&one};
  EXPECT_FALSE(TexelLayer0::available(tp, ones, 1));
  PathGuard guard(TexelLayer0::Path::kPoints);
  EXPECT_FALSE(TexelLayer0::available(tp, mlps, 1));
}

}  // namespace
}  // namespace ks
