#pragma once
// The lift's step 1 (generate/lift.hpp): silhouette offsets. At the posed body's rim, how far the
// photo's mask stands off it (or falls inside it); those values, with soft zeros where the photo
// shows no standoff, smoothed over the whole body by least squares on the base mesh and carried
// to the subdivided mesh: one offset per vertex along its rest normal.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <utility>
#include <vector>

#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "core/image.hpp"
#include "generate/lift.hpp"
#include "generate/lift_body.hpp"
#include "meshrender/meshrender.hpp"

namespace ks::lift {

// Silhouette offsets (metres along the vertex normals) at the body's rim vertices: from each rim
// vertex, along its normal's direction in the image, how far the photo's mask goes on (or, when
// the vertex is already outside the mask, how far inside the mask begins, at most -min_offset).
// A march that meets the body again before the mask ends (a gap the mask fills, e.g. an arm
// against the torso) or runs past max_offset gives no value. V, N: posed vertices and normals;
// body: their render through `cam` (mask, depth).
struct RimOffset {
  int vertex = 0;
  double offset = 0;  // metres, within [min_offset, max_offset]
};
std::vector<RimOffset> rim_offsets(const Eigen::MatrixXd& V, const Eigen::MatrixXd& N,
                                   const Camera& cam, const MeshRenderOutput& body,
                                   const Image& mask, const LiftOptions& o);

// What the smoothing fits: (vertex, offset) pairs with their weights.
struct OffsetTargets {
  std::vector<std::pair<int, double>> targets;
  std::vector<double> weights;
};

// The targets: each rim offset (weight 1) but under the tube (`under_tube`: per body vertex,
// empty for no tube), where the body gets soft zeros instead (w_under_tube_zero); soft zeros
// where the photo sees the surface face-on (w_facing_zero) and on the front of the face
// (w_face_zero).
OffsetTargets offset_targets(const std::vector<RimOffset>& rim,
                             const std::vector<uint8_t>& under_tube, const LiftBody& body,
                             const Camera& cam, const LiftOptions& o);

// The offsets that fit the targets: least squares on the base mesh (unknowns per base vertex,
// carried to the subdivided mesh by `stencil`) with a Laplacian that is weak across body parts,
// clamped to [min_offset, max_offset]. One per row of the stencil.
Eigen::VectorXd smooth_offsets(const Eigen::SparseMatrix<double, Eigen::RowMajor>& stencil,
                               const BodyModel& model, const OffsetTargets& targets,
                               const LiftOptions& o);

}  // namespace ks::lift
