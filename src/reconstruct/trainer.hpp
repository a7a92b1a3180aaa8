#pragma once
// The avatar fit (SinGS GPGS / SIAvatar): Gaussians anchored to the vertices of the
// Loop-subdivided body template in rest pose, attributes from a triplane decoded by two small
// MLPs (reconstruct/decoder.hpp), posed by linear blend skinning to each frame, rendered by the
// differentiable rasterizer, fitted with 0.8 L1 + 0.2 (1 - SSIM) + mask L1 + offset L2 +
// (semantic) Laplacian, Adam with cosine decay; optional features as components
// (reconstruct/components/). Options: reconstruct/options.hpp. Documented in docs/reconstruct.md.
#include <memory>
#include <string>
#include <vector>

#include "avatar/avatar.hpp"
#include "body/body_model.hpp"
#include "dataset/dataset.hpp"
#include "dataset/frames.hpp"
#include "reconstruct/adam.hpp"
#include "reconstruct/options.hpp"

namespace ks {

struct TrainReport {
  int iterations = 0;
  double seconds = 0;
  double ms_per_iteration = 0;
  float final_loss = 0;
  float final_psnr = 0;  // PSNR of the last few training iterations' renders (training frames)
  int num_gaussians = 0;
  // Visibility (TrainOptions::visibility): the steps that decoded only what their frame sees,
  // and the mean share of the Gaussians those decoded.
  int visible_steps = 0;
  double visible_share = 1;
  bool garment = false;         // the skirt proxy was added
  int garment_vertices = 0;     // its vertices (before density control)
  std::string garment_summary;  // detection / proxy line (empty with GarmentMode::kNone)
  float garment_follow = 0;     // the skirt's follow at the end (learned or fixed), at the hem
  std::string garment_follow_profile;  // its value per knot, "/"-separated
};

// One training step's losses (the total and its image terms).
struct StepLosses {
  float total = 0, l1 = 0, ssim = 0, mask = 0;
  double mse = 0;  // of the render against the frame's image
};

// The fit, step by step: set up from the model, the dataset and its frames (loaded with
// load_frames), then step() per iteration, then bake(). train_avatar runs it all.
class Trainer {
 public:
  Trainer(const BodyModel& model, const Dataset& ds, const std::vector<LoadedFrame>& frames,
          const TrainOptions& opt);
  ~Trainer();
  // One iteration: the next frame (shuffled per epoch from the seed), forward, losses,
  // backward, the optimiser, density control.
  StepLosses step();
  // Forward and backward on one frame at the current parameters: returns the losses and leaves
  // their gradients in the optimiser's groups' gradient buffers (by name); no update. What step()
  // computes before the optimiser (tests check the gradients against finite differences of the
  // returned loss).
  StepLosses forward_backward(const LoadedFrame& frame);
  Adam& optimizer();
  // The playback avatar (canonical Gaussians baked, skin weights, skeleton, template, pose
  // correctives when the model has any), ready for save_avatar.
  Avatar bake(TrainReport* report = nullptr);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Fits an avatar to a dataset (frames already loaded with load_frames): Trainer, every step,
// bake.
Avatar train_avatar(const BodyModel& model, const Dataset& ds,
                    const std::vector<LoadedFrame>& frames, const TrainOptions& opt,
                    TrainReport* report = nullptr);

}  // namespace ks
