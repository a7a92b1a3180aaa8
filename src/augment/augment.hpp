#pragma once
// `augment`: SVAD's refinement of a generated dataset, written beside it as PRIOR/refined/ (the
// same frames, poses and masks): identity preservation (face fusion, augment/face_fusion.hpp) in
// every generated frame whose face the camera sees, and an optional external restoration
// command run on each frame. The photo (frame 0) is kept as it is.
#include <string>

namespace ks {

struct AugmentOptions {
  bool face_fusion = true;
  // A frame's face counts as seen when the head's forward direction is within this angle of the
  // direction to the camera.
  double max_face_angle_degrees = 50.0;
  // How the photo's face is carried onto a frame: "body" warps it through the fitted body's
  // surface (the face turns with the head; augment/face_warp.hpp), "similarity" by the 2D
  // similarity of the landmarks (SVAD's; a frontal face stays frontal).
  std::string face_warp = "body";
  // Run on each frame by /bin/sh with {in} and {out} replaced (shell-quoted): a PNG in, a PNG of
  // the same size out (docs/augment.md). Empty: none.
  std::string restore_command;
  bool progress = true;
};

struct AugmentReport {
  int frames = 0;       // generated frames (the photo not counted)
  int faces_fused = 0;  // frames whose face was fused
  int restored = 0;     // frames the restoration command ran on
  double seconds = 0;
};

// Reads PRIOR/dataset (from `generate`) and SUBJECT (image.png, mask.png, fit.json); writes
// PRIOR/refined as a whole (atomically).
AugmentReport run_augment(const std::string& prior_dir, const std::string& subject_dir,
                          const AugmentOptions& options = {});

}  // namespace ks
