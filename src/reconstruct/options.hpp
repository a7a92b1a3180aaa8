#pragma once
// The avatar fit's options, one set of defaults: what `kinesplat reconstruct` uses (its flags only
// override them). Nested per part of the fit; each training component (reconstruct/components/)
// has its own. Documented in docs/reconstruct.md ("Options").
#include <array>
#include <cstdint>
#include <vector>

#include "body/parts.hpp"
#include "dataset/frames.hpp"
#include "reconstruct/garment/proxy.hpp"
#include "reconstruct/losses.hpp"
#include "reconstruct/visibility.hpp"

namespace ks {

class DensityControl;

// The decoders: a triplane sampled at each anchor, two MLPs (geometry: offset, log-scale,
// rotation, opacity; appearance: SH0 colour), and the output activations.
struct DecoderOptions {
  int triplane_res = 512, triplane_channels = 32;
  int hidden = 32;  // width of the MLPs' two hidden layers
  // One MLP decodes geometry and colour (SIAvatar's single D_mlp; group "decoder_mlp") instead
  // of two (groups "geometry_mlp" and "appearance_mlp").
  bool joint = false;
  bool isotropic = true;       // one scale per Gaussian (SIAvatar) instead of three
  float max_offset = 0.06f;    // metres: offset = max_offset * tanh(raw)
  float scale_factor = 0.6f;   // initial scale = scale_factor * mean template edge length
  float init_opacity = 0.95f;  // initial opacity
  // 3D smoothing filter (as Mip-Splatting's): every Gaussian's variance gets filter3d * p^2 added,
  // p = the world size of one training pixel at the body (median over the training frames), so
  // no Gaussian is thinner than the training sampling allows; it stays baked into the exported
  // scales. 0 = off (0.2 did not change the test metrics, docs/reconstruct.md "Measured").
  float filter3d = 0.f;
};

// Loss weights (the total: w_l1 L1 + w_ssim (1 - SSIM) + w_mask mask L1 + w_offset offset L2 +
// the (semantic) Laplacians + what the components add).
struct LossOptions {
  float w_l1 = 0.8f, w_ssim = 0.2f, w_mask = 0.1f, w_offset = 1.0f;
  LaplacianMode laplacian = LaplacianMode::kSemantic;
  std::array<float, kNumParts> part_strength = default_part_strengths();
  float w_lap_position = 10.0f, w_lap_color = 0.01f;
};

// Adam learning rates of the decoders, cosine-decayed to final_fraction of the start.
struct OptimizerOptions {
  float lr_triplane = 2e-2f, lr_mlp = 2e-3f, final_fraction = 0.05f;
};

// Per-vertex colour residual (components/vertex_color.hpp): a free SH0 value per Gaussian added
// to the appearance decoder's output (texture detail finer than the triplane's cells). lr in SH
// units (colour = 0.282 x SH + 0.5); 0 = off.
struct VertexColorOptions {
  float lr = 0.05f;
};

// Learned skin weights (components/learned_skin.hpp, reconstruct/skinning.hpp): a softmax over
// `candidates` joints per Gaussian, initialised to the body's weights, learned from iteration
// from * iterations on, pulled towards the body's weights (w_prior) and smoothed over the
// template (w_laplacian, the anchors' Laplacian). lr in logit units; 0 = the body's weights,
// fixed.
struct LearnedSkinOptions {
  float lr = 0.f;
  int candidates = 8;
  float from = 0.f;
  float w_prior = 0.1f, w_laplacian = 1.0f;
};

enum class GarmentMode { kNone, kSkirt, kAuto };

// The garment layer (components/garment.hpp, reconstruct/garment/): kSkirt adds the skirt proxy
// with `skirt`'s hem; kAuto adds it when detect_skirt finds one in the training masks, with the
// detected hem (subjects without one train as with kNone).
struct GarmentOptions {
  GarmentMode mode = GarmentMode::kAuto;
  SkirtOptions skirt;
  // Learning rate of the skirt's follow profile (logit units; 0 = fixed at skirt.follow), from
  // the image gradient through the skinned means (not with learned skin weights, which own the
  // skinning then).
  float lr_follow = 0.05f;
  bool fit_width = true;  // kAuto: widen the proxy's rings to the measured width
};

struct TrainOptions {
  int iterations = 1600;
  int subdivide = 2;  // Loop subdivision levels of the body template
  uint64_t seed = 0;
  // Frame loading (load_frames): the training resolution relative to the dataset's images, the
  // fine phase's (below) and the imperfect-prior perturbations.
  float scale = 1.f;
  float fine_scale = 1.f;
  PerturbOptions perturb;
  // Coarse-to-fine: from iteration fine_from * iterations on, train on `fine_frames` (the same
  // frames at fine_scale; not owned) instead of the frames. fine_from >= 1 or no fine frames:
  // the whole fit runs on the frames given.
  float fine_from = 1.f;
  const std::vector<LoadedFrame>* fine_frames = nullptr;
  DecoderOptions decoder;
  LossOptions loss;
  OptimizerOptions optimizer;
  VertexColorOptions vertex_color;
  LearnedSkinOptions skin;
  GarmentOptions garment;
  VisibilityOptions visibility;               // decode and draw only what a frame can see
  DensityControl* density_control = nullptr;  // not owned; called after every step
  // The rasterizer's forward and backward on an NVIDIA GPU (raster_cuda/; a build with
  // KS_CUDA): the Gaussians go up and their gradients come back each step, and everything else
  // in the step (decoders, skinning, losses, Adam) stays on the CPU.
  bool cuda_raster = false;
  bool progress = true;
  int log_every = 0;  // > 0: print "it loss psnr" lines to stderr every this many iterations
};

}  // namespace ks
