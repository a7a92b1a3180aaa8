// The decoder with a subset: the decoded Gaussians and the gradients of the parameters are those
// of the whole decode restricted to the subset (the others keep their last values).
#include "reconstruct/decoder.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/error.hpp"

namespace ks {
namespace {

struct Fixture {
  Eigen::MatrixXd anchors;
  Eigen::MatrixXi faces;
  std::vector<float> xs, ys, zs, bias;
  DecoderOptions o;
  Fixture() {
    // A 20 x 20 grid of anchors, bent, with its triangles.
    const int g = 20;
    anchors.resize(g * g, 3);
    for (int y = 0; y < g; ++y)
      for (int x = 0; x < g; ++x)
        anchors.row(y * g + x) << 0.05 * x, 0.05 * y, 0.02 * std::sin(0.5 * x + 0.3 * y);
    faces.resize(2 * (g - 1) * (g - 1), 3);
    int f = 0;
    for (int y = 0; y + 1 < g; ++y)
      for (int x = 0; x + 1 < g; ++x) {
        const int a = y * g + x;
        faces.row(f++) << a, a + 1, a + g;
        faces.row(f++) << a + 1, a + g + 1, a + g;
      }
    for (int i = 0; i < g * g; ++i) {
      xs.push_back(float(anchors(i, 0)));
      ys.push_back(float(anchors(i, 1)));
      zs.push_back(float(anchors(i, 2)));
    }
    bias.assign(size_t(g * g), 0.f);
    o.triplane_res = 16;
    o.triplane_channels = 4;
    o.hidden = 8;
  }
};

TEST(Decoder, SubsetDecodesAndBackpropagatesOnlyItsGaussians) {
  Fixture f;
  const int n = int(f.anchors.rows());
  const float sh0[3] = {0.1f, 0.2f, 0.3f};
  Decoder d;
  d.init(f.o, 3, f.anchors, f.faces, 0.f, sh0);
  Adam adam;
  d.add_parameters(adam, OptimizerOptions{});
  Gaussians whole, part;
  std::vector<float> off_whole, off_part;
  std::vector<int> subset;
  for (int i = 0; i < n; i += 3) subset.push_back(i);
  EXPECT_THROW(d.decode(f.anchors, f.xs, f.ys, f.zs, f.bias, part, off_part, &subset), Error);
  d.decode(f.anchors, f.xs, f.ys, f.zs, f.bias, whole, off_whole);
  // Upstream gradients, zero outside the subset.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  std::vector<float> dm(3 * size_t(n), 0.f), doff(dm.size(), 0.f), dls(dm.size(), 0.f),
      dq(4 * size_t(n), 0.f), dop(size_t(n), 0.f), dsh(dm.size(), 0.f);
  for (int i : subset) {
    for (int k = 0; k < 3; ++k) {
      dm[3 * size_t(i) + k] = U(rng), doff[3 * size_t(i) + k] = U(rng);
      dls[3 * size_t(i) + k] = U(rng), dsh[3 * size_t(i) + k] = U(rng);
    }
    for (int k = 0; k < 4; ++k) dq[4 * size_t(i) + k] = U(rng);
    dop[size_t(i)] = U(rng);
  }
  d.backward(f.xs, f.ys, f.zs, dm, doff, dls, dq, dop, dsh);
  std::vector<std::vector<float>> g_whole;
  for (const AdamGroup& g : adam.groups()) g_whole.push_back(*g.grads);
  // The subset again: its Gaussians decode as before, the others keep the last values.
  d.decode(f.anchors, f.xs, f.ys, f.zs, f.bias, part, off_part, &subset);
  auto same = [](const std::vector<float>& a, const std::vector<float>& b, const char* what) {
    ASSERT_EQ(a.size(), b.size()) << what;
    for (size_t k = 0; k < a.size(); ++k) ASSERT_NEAR(a[k], b[k], 1e-6f) << what << " " << k;
  };
  same(part.means, whole.means, "means");
  same(part.log_scales, whole.log_scales, "log_scales");
  same(part.quats, whole.quats, "quats");
  same(part.opacity_logits, whole.opacity_logits, "opacity");
  same(part.sh, whole.sh, "sh");
  same(off_part, off_whole, "offsets");
  d.backward(f.xs, f.ys, f.zs, dm, doff, dls, dq, dop, dsh);
  size_t gi = 0;
  for (const AdamGroup& g : adam.groups()) {
    const std::vector<float>& a = g_whole[gi++];
    ASSERT_EQ(a.size(), g.grads->size()) << g.name;
    double scale = 0;
    for (float v : a) scale = std::max(scale, double(std::abs(v)));
    EXPECT_GT(scale, 0) << g.name;
    for (size_t k = 0; k < a.size(); ++k)
      ASSERT_NEAR((*g.grads)[k], a[k], 1e-5 * scale) << g.name << " " << k;
  }
  // Other points than the decode's are refused.
  std::vector<float> moved = f.xs;
  moved[0] += 0.01f;
  EXPECT_THROW(d.backward(moved, f.ys, f.zs, dm, doff, dls, dq, dop, dsh), Error);
}

}  // namespace
}  // namespace ks
