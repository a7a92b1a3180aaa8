#pragma once
// The lift's step 2 (generate/lift.hpp): colour from the photo where it sees the surface.
#include <Eigen/Core>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "generate/lift.hpp"
#include "meshrender/meshrender.hpp"

namespace ks::lift {

// The photo's mask with its outline's pixels left out (eroded by a disc of radius max(1,
// round(longer side / outline_side_px)) pixels): they mix the person with the background.
Image inner_mask(const Image& mask, const LiftOptions& o);

// Per vertex: the photo's colour where the camera sees the vertex (in front of the camera, its
// normal facing it by visible_cos or more, no deeper than depth_tolerance behind `depth`'s depth
// and inside `inner`), and how squarely (weight smoothstep(visible_cos, full_view_cos, cosine));
// colour and weight 0 elsewhere.
struct SeenColour {
  Eigen::MatrixXd colour;  // V x 3
  Eigen::VectorXd weight;  // V, in [0, 1]
};
SeenColour seen_colour(const Image& photo, const Image& inner, const Eigen::MatrixXd& vertices,
                       const Eigen::MatrixXd& normals, const MeshRenderOutput& depth,
                       const Camera& cam, const LiftOptions& o);

}  // namespace ks::lift
