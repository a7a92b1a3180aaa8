#pragma once
// Test fixture for the decoder: a bent 20 x 20 grid of anchors with its triangles and a small
// triplane and MLPs; and random upstream gradients of its decoded Gaussians.
#include <Eigen/Core>
#include <cmath>
#include <random>
#include <vector>

#include "reconstruct/options.hpp"

namespace ks::test {

struct DecoderFixture {
  Eigen::MatrixXd anchors;
  Eigen::MatrixXi faces;
  std::vector<float> xs, ys, zs, bias;
  DecoderOptions o;
  DecoderFixture() {
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

// Upstream gradients of n decoded Gaussians and their offsets, uniform in [-1, 1].
struct Upstream {
  std::vector<float> dm, doff, dls, dq, dop,
      dsh;  // means, offsets, log-scales, quats, opacity, SH0
  Upstream(int n, unsigned seed)
      : dm(3 * size_t(n)),
        doff(dm.size()),
        dls(dm.size()),
        dq(4 * size_t(n)),
        dop(size_t(n)),
        dsh(dm.size()) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> U(-1.f, 1.f);
    for (auto* v : {&dm, &doff, &dls, &dq, &dop, &dsh})
      for (float& x : *v) x = U(rng);
  }
};

}  // namespace ks::test
