#pragma once
// The fit stage as a whole: SUBJECT/ (image.png, mask.png, keypoints.json from `perceive`) ->
// SUBJECT/fit.json (and SUBJECT/fit_overlay.png when asked). What `kinesplat fit` and `create` run.
#include <string>

#include "fit/fit.hpp"

namespace ks {

struct FitStageOptions {
  std::string body = "default";  // 'default' or an SMPL-family .npz
  FitOptions fit;
  bool overlay = false;  // also write SUBJECT/fit_overlay.png
};

// Throws ks::Error (naming the file) for missing or malformed inputs; fit.json is written
// atomically, only after the fit succeeded.
FitResult run_fit(const std::string& subject_dir, const FitStageOptions& options = {});

}  // namespace ks
