#pragma once
// The avatar fit (SinGS GPGS / SIAvatar): Gaussians anchored to the vertices of the
// Loop-subdivided body template in rest pose, attributes from a triplane decoded by two small
// MLPs (geometry: offset, log-scale, rotation, opacity; appearance: SH degree-0 colour), posed
// by linear blend skinning to each frame, rendered by the differentiable rasterizer, fitted with
// 0.8 L1 + 0.2 (1 - SSIM) + mask L1 + offset L2 + (semantic) Laplacian, Adam with cosine decay.
// Documented in docs/reconstruct.md.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "avatar/avatar.hpp"
#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "core/image.hpp"
#include "dataset/dataset.hpp"
#include "reconstruct/density.hpp"
#include "reconstruct/garment.hpp"
#include "reconstruct/losses.hpp"

namespace ks {

// SinGS's imperfect-prior setting, applied to the training frames when loading (deterministic
// per seed and frame).
struct PerturbOptions {
  bool enabled = false;
  float color_drift = 0.05f;  // per-frame, per-channel gain 1 +- drift and offset +- drift/2
  float pose_jitter = 0.03f;  // radians, std of Gaussian noise on every body-pose angle
  float warp_pixels = 2.0f;   // max translation of the small affine warp (full-res pixels)
  float warp_degrees = 1.0f;  // max rotation of the warp about the image centre
};

struct TrainFrame;

enum class GarmentMode { kNone, kSkirt, kAuto };

struct TrainOptions {
  int iterations = 2000;
  float scale = 0.5f;  // training resolution relative to the dataset's images
  int subdivide = 2;   // Loop subdivision levels of the body template
  LaplacianMode laplacian = LaplacianMode::kSemantic;
  std::array<float, kNumParts> part_strength = default_part_strengths();
  // Loss weights.
  float w_l1 = 0.8f, w_ssim = 0.2f, w_mask = 0.1f, w_offset = 1.0f;
  float w_lap_position = 10.0f, w_lap_color = 0.01f;
  // Learning rates (Adam), cosine-decayed to lr_final_fraction of the start.
  float lr_triplane = 2e-2f, lr_mlp = 2e-3f, lr_final_fraction = 0.05f;
  // Networks.
  int triplane_res = 128, triplane_channels = 32, hidden = 64;
  bool isotropic = true;     // one scale per Gaussian (SIAvatar) instead of three
  float max_offset = 0.06f;  // metres: offset = max_offset * tanh(raw)
  // Per-vertex colour residual: a free SH0 value per Gaussian added to the appearance decoder's
  // output (texture detail finer than the triplane's cells). Carried through density control by
  // the stencil. lr in SH units (colour = 0.282 x SH + 0.5). 0 = off.
  float lr_vertex_color = 0.f;
  // Learned skin weights (reconstruct/skinning.hpp): a softmax over `skin_candidates` joints per
  // Gaussian, initialised to the body's weights, learned from iteration skin_from * iterations
  // on, pulled towards the body's weights (w_skin_prior) and smoothed over the template
  // (w_lap_skin, the same Laplacian as the anchors'). lr_skin in logit units; 0 = the body's
  // weights, fixed.
  float lr_skin = 0.f;
  int skin_candidates = 8;
  float skin_from = 0.f;
  float w_skin_prior = 0.1f, w_lap_skin = 1.0f;
  // Garment layer (reconstruct/garment.hpp): kSkirt adds the skirt proxy with `skirt`'s hem;
  // kAuto adds it when detect_skirt finds one in the training masks, with the detected hem.
  GarmentMode garment = GarmentMode::kNone;
  SkirtOptions skirt;
  // Learns the skirt's `follow` (one number, in logit units; 0 = fixed at skirt.follow) from the
  // image gradient through the skinned means of the proxy and the body under it.
  float lr_garment_follow = 0.f;
  // kAuto: widen the proxy's rings to the skirt's measured width (detect_skirt's half_width).
  bool garment_fit_width = true;
  float scale_factor = 0.6f;   // initial scale = scale_factor * mean template edge length
  float init_opacity = 0.95f;  // initial opacity
  // 3D smoothing filter (as Mip-Splatting's): every Gaussian's variance gets filter3d * p^2 added,
  // p = the world size of one training pixel at the body (median over the training frames), so
  // no Gaussian is thinner than the training sampling allows; it stays baked into the exported
  // scales, which keeps renders at a higher resolution than the training one free of holes.
  // 0 = off (the default: 0.2 did not change the test metrics, docs/reconstruct.md "Measured").
  float filter3d = 0.f;
  uint64_t seed = 0;
  PerturbOptions perturb;
  DensityControl* density = nullptr;  // not owned; called after every step
  // Coarse-to-fine: from iteration fine_from * iterations on, train on `fine_frames` (the same
  // frames at a higher resolution, usually the dataset's own; not owned) instead of the frames.
  // fine_from >= 1 or fine_frames == nullptr: the whole fit runs on the coarse frames.
  const std::vector<TrainFrame>* fine_frames = nullptr;
  float fine_from = 1.f;
  bool progress = true;
  int log_every = 0;  // > 0: print "it loss psnr" lines to stderr every this many iterations
};

// The 3D smoothing filter on one log-scale: returns log sqrt(exp(2 ls) + var) and writes
// d result / d ls = exp(2 ls) / (exp(2 ls) + var) to *dls. var <= 0: identity.
template <class T>
T filtered_log_scale(T ls, T var, T* dls) {
  if (!(var > T(0))) {
    *dls = T(1);
    return ls;
  }
  const T v = std::exp(T(2) * ls), vf = v + var;
  *dls = v / vf;
  return T(0.5) * std::log(vf);
}

// A training frame, already at training resolution (and perturbed if asked).
struct TrainFrame {
  Image image;  // RGB
  Image mask;   // 1 channel
  Camera camera;
  BodyParams pose;  // betas included
};

// Loads every frame of the dataset at `scale` (area-averaged downsampling; cameras scaled),
// applying the perturbations if enabled. Deterministic for a given seed.
std::vector<TrainFrame> load_training_frames(const Dataset& ds, const std::string& dir, float scale,
                                             const PerturbOptions& perturb, uint64_t seed);
// Scales a camera to a new image size (intrinsics scaled per axis).
Camera scale_camera(const Camera& cam, int width, int height);

struct TrainReport {
  int iterations = 0;
  double seconds = 0;
  double ms_per_iteration = 0;
  float final_loss = 0;
  float final_psnr = 0;  // PSNR of the last few training iterations' renders (training frames)
  int num_gaussians = 0;
  bool garment = false;         // the skirt proxy was added
  int garment_vertices = 0;     // its vertices (before density control)
  std::string garment_summary;  // detection / proxy line (empty with GarmentMode::kNone)
  float garment_follow = 0;     // the skirt's follow at the end (learned or fixed), at the hem
  std::string garment_follow_profile;  // its value per knot, "/"-separated
};

// Fits an avatar to a dataset (frames already loaded with load_training_frames). The result is
// the playback avatar (canonical Gaussians baked, skin weights, skeleton, template, pose
// correctives when the model has any) ready for save_avatar.
Avatar train_avatar(const BodyModel& model, const Dataset& ds,
                    const std::vector<TrainFrame>& frames, const TrainOptions& opt,
                    TrainReport* report = nullptr);

// Convenience: the body model a dataset names ("default" or a path; relative paths are taken
// relative to the dataset directory first).
BodyModel load_dataset_body_model(const Dataset& ds, const std::string& dir);

}  // namespace ks
