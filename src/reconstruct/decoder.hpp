#pragma once
// The avatar fit's decoder (SIAvatar): a triplane sampled at every anchor, decoded by two small
// MLPs (or, with DecoderOptions::joint, one) into the canonical Gaussians, with the output
// activations
//   mean      = anchor + max_offset tanh(o)
//   log_scale = filtered(base + o + per-vertex bias)   (one o per axis, or one shared: isotropic)
//   quat      = (1, 0, 0, 0) + o
//   opacity   = logit(init_opacity) + o
//   sh0       = sh_init + o                            (appearance MLP; joint: its last three)
// Forward (decode) and backward side by side. Its parameter groups ("triplane", "geometry_mlp",
// "appearance_mlp"; joint: "triplane", "decoder_mlp") train with Adam (reconstruct/adam.hpp).
#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "gaussians/gaussians.hpp"
#include "reconstruct/adam.hpp"
#include "reconstruct/mlp.hpp"
#include "reconstruct/options.hpp"
#include "reconstruct/texel_layer0.hpp"
#include "reconstruct/triplane.hpp"

namespace ks {

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

class Decoder {
 public:
  // anchors / faces: the template (rest pose) the triplane's box and the base scale come from;
  // filter_var: the 3D filter's variance (m^2, 0 = off); sh_init: the starting SH0 colour.
  void init(const DecoderOptions& options, uint64_t seed, const Eigen::MatrixXd& anchors,
            const Eigen::MatrixXi& faces, float filter_var, const float sh_init[3]);
  // Registers the three parameter groups with their gradient buffers.
  void add_parameters(Adam& adam, const OptimizerOptions& lr);

  // The canonical Gaussians (SH degree 0) at the anchors (N x 3 rest positions, also given as
  // float arrays xs, ys, zs) with their per-vertex log-scale bias; offsets: 3N anchor offsets.
  // With `subset` (increasing indices), only those Gaussians are decoded; the others keep their
  // values from the decodes before (g and offsets are the whole set either way). Throws
  // ks::Error unless the decode before had the same number of points.
  void decode(const Eigen::MatrixXd& anchors, const std::vector<float>& xs,
              const std::vector<float>& ys, const std::vector<float>& zs,
              const std::vector<float>& log_scale_bias, Gaussians& g, std::vector<float>& offsets,
              const std::vector<int>* subset = nullptr);
  // From the gradients of the decoded Gaussians (dmeans 3N, dlog_scales 3N, dquats 4N,
  // dopacity N, dsh 3N) and of the offsets (doffsets 3N, the offset regularisers) to the
  // parameter groups' gradients. Uses the last decode's state (with a subset, only its
  // Gaussians' gradients are read).
  void backward(const std::vector<float>& xs, const std::vector<float>& ys,
                const std::vector<float>& zs, const std::vector<float>& dmeans,
                const std::vector<float>& doffsets, const std::vector<float>& dlog_scales,
                const std::vector<float>& dquats, const std::vector<float>& dopacity,
                const std::vector<float>& dsh);

  const Triplane& triplane() const { return tp_; }

 private:
  DecoderOptions opt_;
  Triplane tp_;
  Mlp geo_, app_;
  std::vector<float> geo_params_, app_params_;        // packed, what Adam updates
  std::vector<float> dplanes_, geo_grad_, app_grad_;  // their gradients
  MlpCache geo_cache_, app_cache_;
  MlpGrads ggeo_, gapp_;
  Mlp::Mat Yg_, Ya_, dYg_, dYa_, dX_;
  std::vector<float> feats_;        // N x F
  std::vector<float> tanh_off_;     // 3N: tanh of the raw offsets
  std::vector<float> scale_ratio_;  // 3N: d log_scale_filtered / d log_scale (3D filter)
  float base_log_scale_ = 0, init_opacity_logit_ = 0;
  float filter_var_ = 0;
  float sh_init_[3] = {0, 0, 0};
  // The texels any lookup so far has read (only those ever get a gradient), as ranges of
  // entries: Adam steps only these, and backward zeroes only these of dplanes_. The points they
  // were last updated for.
  std::vector<uint8_t> touched_;
  std::vector<std::pair<size_t, size_t>> touched_ranges_;
  std::vector<float> noted_xs_, noted_ys_, noted_zs_;
  TriplaneBins bins_;  // triplane_bins of the noted points
  // The MLPs' first layer in texel space (texel_layer0.hpp), when it serves; whether the last
  // decode took it, and the first layer's pre-activation gradients (both MLPs' rows stacked).
  TexelLayer0 texel0_;
  bool texel0_used_ = false;
  bool texel0_stale_ = true;  // the noted points changed since texel0_.set_points
  std::vector<float> d0_;
  // The last decode's Gaussians and offsets (all points), its subset (empty: all) and that
  // subset's lookup points.
  Gaussians last_;
  std::vector<float> last_offsets_;
  std::vector<int> subset_;
  std::vector<float> sub_xs_, sub_ys_, sub_zs_;
  int sdim_ = 1, geo_out_ = 9;  // geo_out_: the geometry outputs (the joint MLP adds colour)
  bool joint_ = false;
};

}  // namespace ks
