#pragma once
// The sample stage's driving body (SVAD's pose alignment, docs/sample.md): the body model that
// performed the motion, chosen from the options and the motion file, and its skeleton aligned to
// the subject's. Used by run_sample (sample.cpp).
#include <Eigen/Core>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "fit/fit_file.hpp"
#include "sample/pose_align.hpp"
#include "sample/skeleton.hpp"

namespace ks {

// A progress line of the sample stage (printed as "sample: ..." when progress is on).
using SampleNote = std::function<void(const std::string&)>;

struct DrivingBody {
  std::shared_ptr<const BodyModel> model;
  std::string name;       // "default", a path, or the fit's body_model
  Eigen::VectorXd betas;  // the motion's, cut to the model's; empty: the mean shape
  SkeletonSources sources;

  // Pose p on the driving body: its betas, no expression, made valid for its model.
  BodyParams params(const BodyParams& p) const;
  // The driving body's skeleton in pose p, projected through camera.
  Skeleton2D skeleton(const BodyParams& p, const Camera& camera) const;
};

// The driving body for --driving-body `option` (SampleOptions::driving_body): "" picks the fit's
// model when the motion carries betas and the fit's model is not the default one, else none (and
// says why when the betas are left unused); "default" or an .npz path always gives one. Throws
// ks::Error for a model that cannot be read or lacks the skeleton's joints.
std::optional<DrivingBody> choose_driving_body(const std::string& option, const SubjectFit& fit,
                                               const std::optional<Eigen::VectorXd>& motion_betas,
                                               const SampleNote& note);

// Scales from both bodies in the rest pose (a T-pose), oriented and placed as frame 0, seen by the
// camera (so the ratios measure proportions, not foreshortening); offset: their necks in frame 0's
// pose.
PoseAlignment align_driving_body(const DrivingBody& driving, const BodyModel& model,
                                 const SkeletonSources& sources, const BodyParams& frame0,
                                 const Camera& camera);

// "neck 1.000, ..." (the alignment's scales, for the progress line).
std::string alignment_scales_text(const PoseAlignment& alignment);

// Sums of the skeleton points' pixel distances from the subject's own, over frames.
struct AlignmentError {
  double unaligned = 0, aligned = 0;  // pixels
  long points = 0;
  void add(const AlignmentError& e) {
    unaligned += e.unaligned;
    aligned += e.aligned;
    points += e.points;
  }
};

// The driving skeleton of `pose`, aligned; `error` gains its COCO-18 points' distances from the
// subject's own skeleton (`state`, the subject's body in `pose`), before and after aligning.
Skeleton2D aligned_skeleton(const DrivingBody& driving, const PoseAlignment& alignment,
                            const BodyParams& pose, const SkeletonSources& sources,
                            const BodyState& state, const Camera& camera, AlignmentError& error);

}  // namespace ks
