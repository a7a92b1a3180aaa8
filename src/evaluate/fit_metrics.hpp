#pragma once
// A body fit against a known truth (the synth's subject.json): the joints compared in each one's
// camera frame (MPJPE after aligning the pelvis, PA-MPJPE after the best similarity), and the
// silhouettes of the two unclothed bodies, each through its own camera (the fitted camera is
// scaled to the truth's image size when they differ).
#include <array>
#include <nlohmann/json.hpp>
#include <vector>

#include "fit/fit_file.hpp"

namespace ks {

struct FitMetrics {
  int joints = 0;  // joints compared (24: SMPL's skeleton; 22 with SMPL-X)
  double mpjpe_mm = 0;
  double pa_mpjpe_mm = 0;
  double silhouette_iou = 0;
  std::vector<double> pa_per_joint_mm;  // each joint after the Procrustes alignment
  // The shape's error: the two rest-pose bodies (betas only), pelvis on pelvis, mean vertex
  // distance (mm); NaN (JSON null) when the two body models' meshes differ.
  double rest_vertex_error_mm = 0;
  // The joints in each one's camera frame, the pelvis at the origin (what MPJPE compares), mm:
  // a sequence's acceleration error is computed from them.
  std::vector<std::array<double, 3>> estimate_joints_mm, truth_joints_mm;
  nlohmann::json to_json() const;
};

FitMetrics evaluate_fit(const SubjectFit& estimate, const SubjectFit& truth);

// A picture of the two bodies in the truth's camera frame (each body moved into its own camera's
// frame), seen from the camera (view 0) and from the side (view 1), or (view 2) each through its
// own camera as in the photo (what the silhouette IoU compares): the truth's silhouette in green,
// the estimate's in red, overlap yellow.
Image fit_comparison_view(const SubjectFit& estimate, const SubjectFit& truth, int view,
                          int height = 512);

}  // namespace ks
