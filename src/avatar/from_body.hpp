#pragma once
// A plain avatar straight from a body model: one Gaussian per vertex of the (optionally
// subdivided) shaped template, uniform colour and size, skin weights and part labels carried by the
// subdivision stencil. The starting point of a fit, and a test / demo fixture for playback.
#include <Eigen/Core>

#include "avatar/avatar.hpp"
#include "body/body_model.hpp"

namespace ks {

struct PlainAvatarOptions {
  int subdivide = 0;          // Loop subdivision levels
  float scale_factor = 0.6f;  // Gaussian std = scale_factor * mean template edge length
  float opacity = 0.95f;
  float color[3] = {0.7f, 0.7f, 0.7f};
  bool posedirs = true;  // store the template's pose correctives (if the model has non-zero ones)
};

Avatar avatar_from_body(const BodyModel& model, const Eigen::VectorXd& betas,
                        const PlainAvatarOptions& opt = {});

}  // namespace ks
