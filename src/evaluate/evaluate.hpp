#pragma once
// Evaluates a trained avatar against a dataset: every frame rendered with the posed avatar on the
// dataset's background at the dataset's resolution (or `scale` of it), PSNR and SSIM over the full
// frame and inside the mask, per frame and averaged; optionally also after registering each
// frame's pose to its image (test-time pose refinement, `evaluate --register`).
#include <string>
#include <vector>

#include "avatar/avatar.hpp"
#include "dataset/dataset.hpp"
#include "evaluate/metrics.hpp"
#include "register/register.hpp"

namespace ks {

// Per-frame figures and their averages, over all frames and by view.
struct EvalFigures {
  std::vector<ImageMetrics> frames;
  ImageMetrics mean;  // averages over frames (masked values over frames with a non-empty mask)
  ImageMetrics by_view[3];  // front, side, back (EvalReport::view)
  int view_frames[3] = {0, 0, 0};
  void add(const ImageMetrics& m, int view);
  void finish();  // sums -> averages
  int masked_frames = 0;
};

struct EvalReport : EvalFigures {
  // Per frame, the angle between the body's forward direction (the posed pelvis' +Z) and the
  // direction to the camera: front < 45 degrees, back > 135, side between.
  std::vector<std::string> view;  // "front", "side" or "back"
  double ms_per_render = 0;
  // With registration (evaluate_avatar's `registration`): the same figures after each frame's
  // pose was registered to its image (register/register.hpp), and per frame what it did.
  bool registered_run = false;
  EvalFigures registered;
  std::vector<RegisterResult> registration;
  double ms_per_register = 0;
  nlohmann::json to_json(const Dataset& ds) const;
};

// `render_dir`: if not empty, writes the renders there as PNG (render_0000.png, ...; with
// registration also registered_0000.png, ...). `registration`: if given, each frame is also
// measured after registering its pose to the frame (the avatar fixed), beside the plain figures.
EvalReport evaluate_avatar(const Avatar& avatar, const Dataset& ds, const std::string& dir,
                           float scale = 1.f, const std::string& render_dir = "",
                           bool progress = true, const RegisterOptions* registration = nullptr);

}  // namespace ks
