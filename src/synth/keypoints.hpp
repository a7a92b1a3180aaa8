#pragma once
// BODY_25 keypoints of a synthetic person: where each comes from (a joint, the mean of two
// joints, or a surface vertex found by landmarks) and their 2D positions and visibility in a
// render.
#include <Eigen/Core>
#include <array>

#include "body/keypoints.hpp"
#include "meshrender/meshrender.hpp"
#include "synth/appearance.hpp"
#include "synth/person.hpp"

namespace ks {

// Fills P.kp_joint / kp_joint2 / kp_vertex / kp_depth_tolerance from the displaced rest surface
// (P.rest), the undisplaced one (V0) with its normals, and the landmarks.
void assign_keypoint_sources(SynthPerson& P, const Eigen::MatrixXd& V0,
                             const Eigen::MatrixXd& normals, const Landmarks& L);

// BODY_25 keypoints (x, y, confidence) from the projected joints and surface points: confidence
// 1 where the point is inside the image and not hidden (depth test against `render.depth`,
// which must have been rendered with the same camera), 0 otherwise (x = y = 0 then).
std::array<Eigen::Vector3d, kBody25Count> synth_keypoints(const SynthPerson& person,
                                                          const PosedPerson& posed,
                                                          const Camera& camera,
                                                          const MeshRenderOutput& render);
}  // namespace ks
