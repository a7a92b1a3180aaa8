#pragma once
// The lift's step 3 (generate/lift.hpp): colour for what the photo does not see, from what it
// does: the other side's limb (left <-> right), the other face of the body (front <-> back), and
// at the back of the head the hair's colour (above the nape's hairline) or the nape's.
#include <Eigen/Core>
#include <vector>

#include "body/lbs.hpp"
#include "generate/lift.hpp"
#include "generate/lift_body.hpp"
#include "generate/lift_seen.hpp"

namespace ks::lift {

// Index of each vertex's mirror image (x -> 2 cx - x), -1 if none within `radius` (metres).
std::vector<int> mirror_left_right(const Eigen::MatrixXd& V, double cx, double radius);

// Index of each vertex's front/back mirror: the point reflected in depth (z) about the closest
// point of its main bone (its first skin joint to that joint's first child, or on from its parent
// for a leaf), among the vertices whose normal's z has the other sign; -1 if none within `radius`.
std::vector<int> mirror_front_back(const Eigen::MatrixXd& V, const Eigen::MatrixXd& normals,
                                   const SkinJoints& skin_joints, const std::vector<int>& parents,
                                   const Eigen::MatrixXd& joints, double radius);

// Both mirrors of the lifted mesh at rest (V, its normals; the body's rest joints), each empty
// when its LiftOptions switch is off; radii in the mesh's mean edge lengths.
struct Mirrors {
  std::vector<int> left_right, front_back;
};
Mirrors find_mirrors(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F,
                     const Eigen::MatrixXd& normals, const SkinJoints& skin_joints,
                     const LiftBody& body, const LiftOptions& o);

// The head's colours from the seen ones (body vertices first in `seen`): the hair's, the median
// of the seen crown, and the nape's, the median of the sides of the head and neck below the
// hairline (long hair hangs there; else the neck's skin), the hair's when nothing is seen there.
struct HeadColours {
  Eigen::Vector3d hair = Eigen::Vector3d::Zero();
  Eigen::Vector3d nape = Eigen::Vector3d::Zero();
};
HeadColours head_colours(const SeenColour& seen, const LiftBody& body, const LiftOptions& o);

// The blend per vertex: the seen colour (its weight) with the mirrors' seen colours and the
// head's rule (LiftOptions' w_* factors times (1 - seen weight)^2, mirrors times their seen
// weight; the back of the head never gets the face mirrored). `mirrors` as find_mirrors gives.
struct Blend {
  Eigen::MatrixXd colour;  // V x 3, the weighted mean (0 where nothing contributes)
  Eigen::VectorXd weight;  // V, the weights' sum
  int seen = 0;            // vertices of seen weight counted_seen or more
  int mirrored = 0;        // of the others, vertices of total weight known_weight or more
};
Blend blend_colours(const SeenColour& seen, const Mirrors& mirrors, const HeadColours& head,
                    const LiftBody& body, const LiftOptions& o);

}  // namespace ks::lift
