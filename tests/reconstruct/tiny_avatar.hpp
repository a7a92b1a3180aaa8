#pragma once
// Test fixture: an avatar with the trainer's own structure (template, skin weights, decoded
// attributes) after a single step on a blank 40x56 frame, for tests to paint as ground truth.
#include "core/camera.hpp"
#include "reconstruct/trainer.hpp"

namespace ks::test {

inline Avatar one_step_avatar(const BodyModel& model, const Dataset& ds, TrainOptions opt) {
  opt.iterations = 1;
  std::vector<TrainFrame> blank(1);
  blank[0].image = Image(40, 56, 3, 1.f);
  blank[0].mask = Image(40, 56, 1, 0.f);
  blank[0].camera = Camera::look_at_fov({0, 0, 3.2}, {0, -0.3, 0}, 40, 56, 45.0);
  blank[0].pose.betas = ds.betas;
  return train_avatar(model, ds, blank, opt);
}

}  // namespace ks::test
