#pragma once
// `track`'s temporal solve: every frame of a sequence (a video, a folder of frames) fitted at once,
// the shared shape fixed, each frame with the single-photo fit's keypoint and prior terms
// terms (fit/terms.hpp; the silhouette's only with `silhouette`) and the
// temporal terms (track/temporal_terms.hpp) tying each frame's joints and BODY_25 points to its
// neighbours', starting from the per-frame fits. Robust to the detector's failures:
//  - dropouts and brief occlusions: a keypoint missing in a frame has no term there; the
//    neighbours' motion places it;
//  - left/right swaps: after a solve, each frame's detections are compared with where its
//    neighbours put the body (interpolated in time, projected); where the keypoints of the legs,
//    the arms or the whole body read with left and right exchanged match it much better, the
//    frame's labels are exchanged;
//  - a frame in the wrong minimum (a stride's legs the other way round in depth): its points far
//    from its neighbours' interpolation (beyond `reinit_deviations` of the acceleration term's
//    deviation) restart from that interpolation.
// After swaps or restarts the sequence is solved again, and kept only when its total cost falls.
#include <Eigen/Core>
#include <vector>

#include "body/body_model.hpp"
#include "fit/fit.hpp"

namespace ks {

struct TemporalOptions {
  bool enabled = true;  // on sequences of at least 3 frames
  // The acceleration term's deviation density (m s^-1.5, track/temporal_terms.hpp); <= 0: none.
  double sigma_accel = 6.0;
  // The velocity term's (m s^-0.5); <= 0: none.
  double sigma_velocity = 0.0;
  // Cauchy scale of each point's temporal residual, in its deviations (<= 0: quadratic): a
  // point's genuine peaks (a foot's swing) cost little more than a few deviations.
  double temporal_robust = 3.0;
  int joints =
      22;  // the body joints followed (SMPL's 22 without the hands), and the BODY_25 points
  // The single-photo fit's silhouette terms (inside and cover) where a frame has a mask, the
  // cover term's correspondences renewed before each of `silhouette_rounds` solves. Off: on the
  // tuning seed (synth 3, walk) it kept the silhouette IoU (0.888 against 0.854 without, 0.893
  // pass 2) but cost 18 mm MPJPE and 26 mm PA-MPJPE against pass 3 without it, and 10x the time.
  bool silhouette = false;
  int silhouette_rounds = 2;
  bool fix_swaps = true;
  // A swap is taken where the exchanged labels' robust cost against the neighbours' prediction is
  // below this fraction of the labels as given.
  double swap_ratio = 0.5;
  // A frame restarts from its neighbours where its points (RMS) lie this many deviations from
  // their interpolation; <= 0: never.
  double reinit_deviations = 4.0;
  int max_iterations = 50;
  bool progress = false;
};

struct TemporalReport {
  bool applied = false;
  double cost_before = 0, cost_after = 0;  // the sequence's total (frames' terms + temporal)
  double temporal_cost = 0;                // the temporal terms' part of cost_after
  std::vector<int> swapped;                // positions (in the frames given) whose labels changed
  std::vector<int> restarted;              // positions restarted from their neighbours
  int solves = 0;
  double seconds = 0;
};

// Refines `fits` (one per frame, in time order at `times` seconds; the shape `betas` fixed) in
// place; frame f's `costs` become its own terms' costs in the final solve ("total" their sum).
// `inputs`' keypoints are exchanged where a swap was taken (what the fits now explain).
// With fewer than 3 frames, or options.enabled false, nothing changes (applied false).
TemporalReport solve_temporal(const BodyModel& model, std::vector<FitInput>& inputs,
                              const std::vector<double>& times, const Eigen::VectorXd& betas,
                              std::vector<FitResult>& fits, const FitOptions& fit_options,
                              const TemporalOptions& options = {});

}  // namespace ks
