// The decoder with a subset: the decoded Gaussians and the gradients of the parameters are those
// of the whole decode restricted to the subset (the others keep their last values). The
// template's numbering (the trainer numbers it along a Morton curve) does not show: its vertices
// in another order decode to the same Gaussians.
#include "reconstruct/decoder.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "reconstruct/decoder_fixture.hpp"

namespace ks {
namespace {

using test::DecoderFixture;
using test::Upstream;

TEST(Decoder, SubsetDecodesAndBackpropagatesOnlyItsGaussians) {
  DecoderFixture f;
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

// The same template with its vertices renumbered: every Gaussian decodes to the same bits (a
// point's features and MLP outputs do not depend on where it is numbered), and the same upstream
// gradients, renumbered, give the parameters the same gradients up to the order of the sums.
TEST(Decoder, VertexOrderDoesNotChangeTheGaussians) {
  DecoderFixture f;
  const int n = int(f.anchors.rows());
  std::vector<int> perm(static_cast<size_t>(n));  // new vertex k is old vertex perm[k]
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(11));
  std::vector<int> inv(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) inv[size_t(perm[size_t(k)])] = k;
  DecoderFixture g = f;
  for (int k = 0; k < n; ++k) {
    const size_t o = size_t(perm[size_t(k)]);
    g.anchors.row(k) = f.anchors.row(long(o));
    g.xs[size_t(k)] = f.xs[o], g.ys[size_t(k)] = f.ys[o], g.zs[size_t(k)] = f.zs[o];
  }
  for (long r = 0; r < g.faces.rows(); ++r)
    for (int c = 0; c < 3; ++c) g.faces(r, c) = inv[size_t(f.faces(r, c))];
  const float sh0[3] = {0.1f, 0.2f, 0.3f};
  const Upstream u(n, 5);
  const std::vector<float>&dm = u.dm, &doff = u.doff, &dls = u.dls, &dq = u.dq, &dop = u.dop,
        &dsh = u.dsh;
  auto renumber = [&](const std::vector<float>& v, int dim) {
    std::vector<float> r(v.size());
    for (int k = 0; k < n; ++k)
      for (int c = 0; c < dim; ++c)
        r[size_t(dim) * size_t(k) + size_t(c)] =
            v[size_t(dim) * size_t(perm[size_t(k)]) + size_t(c)];
    return r;
  };
  struct Run {
    Gaussians gs;
    std::vector<float> off;
    std::vector<std::vector<float>> grads;
  };
  auto run = [&](const DecoderFixture& x, bool renumbered) {
    Decoder d;
    d.init(x.o, 3, x.anchors, x.faces, 0.f, sh0);
    Adam adam;
    d.add_parameters(adam, OptimizerOptions{});
    Run r;
    d.decode(x.anchors, x.xs, x.ys, x.zs, x.bias, r.gs, r.off);
    auto up = [&](const std::vector<float>& v, int dim) {
      return renumbered ? renumber(v, dim) : v;
    };
    d.backward(x.xs, x.ys, x.zs, up(dm, 3), up(doff, 3), up(dls, 3), up(dq, 4), up(dop, 1),
               up(dsh, 3));
    for (const AdamGroup& a : adam.groups()) r.grads.push_back(*a.grads);
    return r;
  };
  const Run a = run(f, false), b = run(g, true);
  EXPECT_EQ(renumber(a.gs.means, 3), b.gs.means);
  EXPECT_EQ(renumber(a.gs.log_scales, 3), b.gs.log_scales);
  EXPECT_EQ(renumber(a.gs.quats, 4), b.gs.quats);
  EXPECT_EQ(renumber(a.gs.opacity_logits, 1), b.gs.opacity_logits);
  EXPECT_EQ(renumber(a.gs.sh, 3), b.gs.sh);
  EXPECT_EQ(renumber(a.off, 3), b.off);
  ASSERT_EQ(a.grads.size(), b.grads.size());
  for (size_t q = 0; q < a.grads.size(); ++q) {
    ASSERT_EQ(a.grads[q].size(), b.grads[q].size());
    double scale = 0;
    for (float v : a.grads[q]) scale = std::max(scale, double(std::abs(v)));
    EXPECT_GT(scale, 0);
    for (size_t k = 0; k < a.grads[q].size(); ++k)
      ASSERT_NEAR(a.grads[q][k], b.grads[q][k], 1e-5 * scale) << q << " " << k;
  }
}

// The decoder's backward against central differences of its own decode, for the two MLPs and
// the joint one: L = the decoded Gaussians and offsets weighted by fixed random upstream
// gradients; with 4 and 8 triplane channels (8: the first layers in texel space, where the CPU has
// AVX2); every parameter group's eight largest entries (the loss summed in double from float
// decodes: steps of 1e-4, small enough for the ReLUs' and tanh's curvature, with a 3 % tolerance
// plus 1 % of the largest difference for float noise).
TEST(Decoder, BackwardMatchesFiniteDifferencesSplitAndJoint) {
  DecoderFixture f;
  const int n = int(f.anchors.rows());
  const float sh0[3] = {0.1f, 0.2f, 0.3f};
  const Upstream u(n, 7);
  const std::vector<float>&dm = u.dm, &doff = u.doff, &dls = u.dls, &dq = u.dq, &dop = u.dop,
        &dsh = u.dsh;
  // 8 channels: the first layers in texel space where the CPU has AVX2 (texel_layer0.hpp).
  for (const int channels : {4, 8})
    for (const bool joint : {false, true}) {
      DecoderOptions o = f.o;
      o.joint = joint;
      o.triplane_channels = channels;
      o.max_offset = 0.2f;
      Decoder d;
      d.init(o, 3, f.anchors, f.faces, 0.f, sh0);
      Adam adam;
      d.add_parameters(adam, OptimizerOptions{});
      EXPECT_EQ(adam.has_group("decoder_mlp"), joint);
      EXPECT_EQ(adam.has_group("appearance_mlp"), !joint);
      auto loss = [&] {
        Gaussians g;
        std::vector<float> off;
        d.decode(f.anchors, f.xs, f.ys, f.zs, f.bias, g, off);
        double l = 0;
        for (size_t k = 0; k < dm.size(); ++k)
          l += double(dm[k]) * g.means[k] + double(doff[k]) * off[k] +
               double(dls[k]) * g.log_scales[k] + double(dsh[k]) * g.sh[k];
        for (size_t k = 0; k < dq.size(); ++k) l += double(dq[k]) * g.quats[k];
        for (size_t k = 0; k < dop.size(); ++k) l += double(dop[k]) * g.opacity_logits[k];
        return l;
      };
      // Larger last-layer weights than the init's, so that every output moves with the features.
      std::vector<std::string> names;
      for (const AdamGroup& g : adam.groups()) names.push_back(g.name);
      for (const std::string& name : names)
        if (name != "triplane")
          for (float& v : *adam.group(name).params) v *= 3.f;
      loss();
      d.backward(f.xs, f.ys, f.zs, dm, doff, dls, dq, dop, dsh);
      for (const std::string& name : names) {
        AdamGroup& g = adam.group(name);
        const std::vector<float> grad = *g.grads;
        std::vector<size_t> idx(grad.size());
        std::iota(idx.begin(), idx.end(), size_t(0));
        std::partial_sort(idx.begin(), idx.begin() + 8, idx.end(), [&](size_t a, size_t b) {
          return std::abs(grad[a]) > std::abs(grad[b]);
        });
        idx.resize(8);
        std::vector<double> fd;
        double largest = 0;
        for (size_t i : idx) {
          float& p = (*g.params)[i];
          const float keep = p;
          const float h = 1e-4f;
          p = keep + h;
          const double lp = loss();
          p = keep - h;
          const double lm = loss();
          p = keep;
          fd.push_back((lp - lm) / (2.0 * double(h)));
          largest = std::max(largest, std::abs(fd.back()));
        }
        EXPECT_GT(largest, 1e-3) << g.name;
        for (size_t q = 0; q < idx.size(); ++q)
          EXPECT_NEAR(grad[idx[q]], fd[q], 0.03 * std::abs(fd[q]) + 0.01 * largest)
              << (joint ? "joint " : "split ") << channels << " channels " << g.name << "["
              << idx[q] << "]";
      }
    }
}

}  // namespace
}  // namespace ks
