#pragma once
// Registration by analysis-by-synthesis: a frame's body pose and global transform optimised so
// that the avatar's render matches the frame, the avatar (its Gaussians, skin and shape) fixed.
// The loss, over the person's pixels (normalised by the mask's area):
//   E = w_c |C - T|^2 / 3 + w_m (alpha - m)^2 + w_p sum_j |theta_j - theta0_j|^2 / J_body
// with C, alpha the render (on the background) and T the frame composited on the same background
// by its mask m; theta the body joints' axis-angles (the root's orientation and the translation
// are free). Adam on the pose, coarse to fine (the image and camera scaled), through the project's
// own rasterizer backward, LBS and forward kinematics backward (avatar/pose.hpp). The result is
// kept only where the finest level's cost fell. Documented in docs/register.md.
#include <vector>

#include "avatar/avatar.hpp"
#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "core/image.hpp"

namespace ks {

struct RegisterOptions {
  // Coarse to fine: image scales (of the frame's own size) and Adam steps at each.
  std::vector<float> scales = {0.5f, 1.f};
  std::vector<int> iterations = {30, 40};
  float lr_rotation = 0.01f;     // rad per step at the start (cosine decay to a tenth)
  float lr_translation = 0.01f;  // m per step
  float colour_weight = 1.f;
  float mask_weight = 1.f;
  float pose_prior = 0.02f;  // per rad^2 of a body joint's change, averaged over joints
  bool body_joints = true;   // false: the root's orientation and the translation only
};

struct RegisterResult {
  BodyParams params;  // the registered pose (the start's where nothing improved)
  // At the finest scale: the loss and its colour and mask parts, before and after.
  double cost_before = 0, cost_after = 0;
  double colour_before = 0, colour_after = 0, mask_before = 0, mask_after = 0;
  bool improved = false;  // false: the start is returned
  int steps = 0;
  double seconds = 0;
};

// `image` RGB, `mask` one channel of the same size (empty: the whole frame is the person, and
// the mask term is off), `camera` for the image's size. Throws ks::Error for inconsistent sizes
// or options.
RegisterResult register_pose(const Avatar& avatar, const BodyParams& start, const Camera& camera,
                             const Image& image, const Image& mask, const float background[3],
                             const RegisterOptions& options = {});

}  // namespace ks
