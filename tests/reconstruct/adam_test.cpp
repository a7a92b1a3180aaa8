#include "reconstruct/adam.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace ks {

TEST(Adam, MinimisesQuadraticWithCosineDecay) {
  std::vector<float> p = {3.f, -2.f, 0.5f}, q = {1.f};
  Adam adam;
  adam.total_steps = 400;
  adam.add_group("p", &p, 0.05f);
  adam.add_group("q", &q, 0.0f);  // lr 0: never moves
  std::vector<float> gp(3), gq(1);
  for (int it = 0; it < 400; ++it) {
    for (int i = 0; i < 3; ++i) gp[i] = 2 * (p[i] - float(i));
    gq[0] = 1.f;
    adam.step({&gp, &gq});
  }
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(p[i], float(i), 1e-2);
  EXPECT_EQ(q[0], 1.f);
  EXPECT_NEAR(adam.lr_scale(), adam.final_fraction, 1e-6);
}

TEST(Adam, ResizeAndRemapKeepMoments) {
  std::vector<float> p = {1, 2, 3, 4, 5, 6};
  Adam adam;
  adam.add_group("p", &p, 0.1f);
  std::vector<float> g = {1, 1, 1, -1, -1, -1};
  adam.step({&g});
  const float m3 = adam.group(0).m[3];
  // Per-vertex stride 3: keep vertex 1 first, then a new vertex.
  adam.remap_group(0, {1, -1}, 3);
  EXPECT_EQ(adam.group(0).m.size(), 6u);
  EXPECT_EQ(adam.group(0).m[0], m3);
  EXPECT_EQ(adam.group(0).m[3], 0.f);
  p.resize(9, 0.f);
  adam.resize_group(0);
  EXPECT_EQ(adam.group(0).v.size(), 9u);
  std::vector<float> g9(9, 0.5f);
  adam.step({&g9});
  std::vector<float> wrong(2, 0.f);
  EXPECT_THROW(adam.step({&wrong}), std::exception);
  EXPECT_THROW(adam.remap_group(0, {7}, 3), std::exception);
}

}  // namespace ks
