#pragma once
// The fit's per-frame terms as one stage switches them on: keypoints, the pose prior and joint
// limits, arms out of the torso, upright, ground, shape prior; and the silhouette (inside and
// cover) with its correspondences. The single-photo fit (fit.cpp) adds them for its one frame;
// `track`'s temporal solve (track/temporal.hpp) adds them for every frame of a sequence, beside
// its temporal terms.
#include <ceres/ceres.h>

#include <map>
#include <string>
#include <vector>

#include "fit/evaluator.hpp"
#include "fit/fit.hpp"
#include "fit/pose_prior.hpp"
#include "fit/silhouette.hpp"

namespace ks::fit {

// A stage's residual blocks by term name, for the per-term costs.
using TermBlocks = std::map<std::string, std::vector<ceres::ResidualBlockId>>;

// BODY_25 point k's weight relative to the body's points: the face's and the feet's from the
// options, 1 elsewhere.
double keypoint_group_weight(int k, const FitOptions& o);

// Neck, shoulders, mid-hip and hips: what a torso-only stage fits.
bool is_torso_keypoint(int k);

// The person's height in pixels: the mask's rows, else the keypoints' extent (and 15 % more for
// what lies above the eyes and below the ankles). The fit's residual unit is 1 % of it.
double person_height_px(const FitInput& in);

// One frame as its terms read it.
struct FrameTerms {
  const BodyData& d;
  const FitInput& in;
  const Evaluator& ev;  // the frame's body at x
  const Projector& pr;
  const std::vector<JointPrior>& priors;  // make_joint_priors of d
  double unit = 1;                        // pixels per residual unit
};

// Stage s's terms (all but the silhouette) on the frame's packed parameters x, each term's blocks
// under its name in `groups`.
void add_frame_terms(ceres::Problem& problem, const FrameTerms& f, const FitOptions& o,
                     const FitStage& s, double* x, TermBlocks& groups);

// Correspondences of the cover term: each mask-outline sample with its nearest body-outline
// vertex (a slot of d's vertex subset), the body rendered with parameters p through `camera`.
struct Cover {
  int vertex;
  Eigen::Vector2d q;
};
std::vector<Cover> cover_correspondences(const BodyModel& model, const BodyData& d,
                                         const BodyParams& p, const Camera& camera,
                                         const Image& mask);

// The silhouette terms on x: every subset vertex outside the mask (`df`, its outside distance;
// the frame's Evaluator must hold all the subset's vertices) and the mask's outline against its
// `covers` beyond the clothing allowance.
void add_silhouette_terms(ceres::Problem& problem, const FrameTerms& f, const DistanceField& df,
                          const std::vector<Cover>& covers, const FitOptions& o, double* x,
                          TermBlocks& groups);

}  // namespace ks::fit
