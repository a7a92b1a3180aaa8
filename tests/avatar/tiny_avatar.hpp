#pragma once
// A tiny hand-built avatar for tests: an octahedron of 6 Gaussians around a 3-joint chain
// (root at the origin, joint 1 at (0, 0.5, 0), joint 2 at (0, 1, 0)).
#include <cmath>

#include "avatar/avatar.hpp"

namespace ks::test {

inline Avatar tiny_avatar(int sh_degree = 0) {
  Avatar a;
  a.body_kind = "default";
  a.body_model = "default";
  a.betas = Eigen::VectorXd::Zero(2);
  a.parents = {-1, 0, 1};
  a.joint_names = {"pelvis", "spine", "head"};
  a.rest_joints.resize(3, 3);
  a.rest_joints << 0, 0, 0, 0, 0.5, 0, 0, 1.0, 0;
  a.template_vertices.resize(6, 3);
  a.template_vertices << 0.3, 0.5, 0, -0.3, 0.5, 0, 0, 1.1, 0, 0, -0.1, 0, 0, 0.5, 0.3, 0, 0.5,
      -0.3;
  a.template_faces.resize(8, 3);
  a.template_faces << 0, 2, 4, 4, 2, 1, 1, 2, 5, 5, 2, 0, 0, 4, 3, 4, 1, 3, 1, 5, 3, 5, 0, 3;
  const int N = 6;
  a.gaussians.sh_degree = sh_degree;
  a.gaussians.resize(N);
  a.anchors.resize(3 * N);
  a.skin_joints.assign(4 * N, 0);
  a.skin_weights.assign(4 * N, 0.f);
  a.part_labels.resize(N);
  const int K = a.gaussians.coeffs();
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < 3; ++k) {
      a.anchors[3 * i + k] = float(a.template_vertices(i, k));
      a.gaussians.means[3 * i + k] = a.anchors[3 * i + k] + 0.01f * float(k + 1);
      a.gaussians.log_scales[3 * i + k] = std::log(0.05f + 0.01f * k);
    }
    const float ang = 0.3f * float(i);
    a.gaussians.quats[4 * i] = std::cos(ang / 2);
    a.gaussians.quats[4 * i + 1] = std::sin(ang / 2) * 0.6f;
    a.gaussians.quats[4 * i + 2] = std::sin(ang / 2) * 0.8f;
    a.gaussians.quats[4 * i + 3] = 0.f;
    a.gaussians.opacity_logits[i] = 2.0f;
    for (int k = 0; k < K; ++k)
      for (int c = 0; c < 3; ++c)
        a.gaussians.sh[(size_t(i) * K + k) * 3 + c] = 0.1f * c - 0.05f * k;
    // Lower vertices on the root, upper on joint 2, middle shared.
    const float y = a.anchors[3 * i + 1];
    if (y > 1.0f) {
      a.skin_joints[4 * i] = 2;
      a.skin_weights[4 * i] = 1.f;
    } else if (y < 0.f) {
      a.skin_joints[4 * i] = 0;
      a.skin_weights[4 * i] = 1.f;
    } else {
      a.skin_joints[4 * i] = 1;
      a.skin_joints[4 * i + 1] = 0;
      a.skin_weights[4 * i] = 0.7f;
      a.skin_weights[4 * i + 1] = 0.3f;
    }
    a.part_labels[i] = i % 3;
  }
  a.metadata = {{"test", true}};
  return a;
}

}  // namespace ks::test
