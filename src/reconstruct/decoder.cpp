#include "reconstruct/decoder.hpp"

#include <algorithm>

#include "core/error.hpp"
#include "core/parallel_copy.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

void Decoder::init(const DecoderOptions& o, uint64_t seed, const Eigen::MatrixXd& anchors,
                   const Eigen::MatrixXi& faces, float filter_var, const float sh_init[3]) {
  opt_ = o;
  {
    const Eigen::Vector3d lo = anchors.colwise().minCoeff(), hi = anchors.colwise().maxCoeff();
    const double pad = 0.05 + o.max_offset;
    const float blo[3] = {float(lo.x() - pad), float(lo.y() - pad), float(lo.z() - pad)};
    const float bhi[3] = {float(hi.x() + pad), float(hi.y() + pad), float(hi.z() + pad)};
    tp_.init(o.triplane_res, o.triplane_channels, blo, bhi, seed * 3 + 1, 0.1f);
  }
  sdim_ = o.isotropic ? 1 : 3;
  geo_out_ = 3 + sdim_ + 4 + 1;
  const int F = tp_.feature_dim();
  joint_ = o.joint;
  // Joint: one MLP whose last three outputs are the colour (the appearance MLP stays empty).
  geo_.init({F, o.hidden, o.hidden, geo_out_ + (joint_ ? 3 : 0)}, seed * 3 + 2, 0.01f);
  if (joint_)
    app_ = Mlp{};
  else
    app_.init({F, o.hidden, o.hidden, 3}, seed * 3 + 3, 0.01f);
  base_log_scale_ = float(std::log(o.scale_factor * mean_face_edge_length(anchors, faces)));
  init_opacity_logit_ = std::log(o.init_opacity / (1.f - o.init_opacity));
  filter_var_ = filter_var;
  for (int k = 0; k < 3; ++k) sh_init_[k] = sh_init[k];
  geo_.pack(geo_params_);
  app_params_.clear();
  if (!joint_) app_.pack(app_params_);
  dplanes_.assign(tp_.size(), 0.f);
  touched_.assign(tp_.size() / size_t(tp_.channels), 0);
  touched_ranges_.clear();
  last_ = Gaussians{};
  last_offsets_.clear();
  subset_.clear();
  noted_xs_.clear(), noted_ys_.clear(), noted_zs_.clear();
  bins_ = TriplaneBins{};
  texel0_stale_ = true;
  geo_grad_.assign(geo_params_.size(), 0.f);
  app_grad_.assign(app_params_.size(), 0.f);
}

void Decoder::add_parameters(Adam& adam, const OptimizerOptions& lr) {
  adam.add_group("triplane", &tp_.planes, &dplanes_, lr.lr_triplane, &touched_ranges_);
  if (joint_) {
    adam.add_group("decoder_mlp", &geo_params_, &geo_grad_, lr.lr_mlp);
    return;
  }
  adam.add_group("geometry_mlp", &geo_params_, &geo_grad_, lr.lr_mlp);
  adam.add_group("appearance_mlp", &app_params_, &app_grad_, lr.lr_mlp);
}

void Decoder::decode(const Eigen::MatrixXd& anchors, const std::vector<float>& xs,
                     const std::vector<float>& ys, const std::vector<float>& zs,
                     const std::vector<float>& log_scale_bias, Gaussians& g,
                     std::vector<float>& offsets, const std::vector<int>* subset) {
  geo_.unpack(geo_params_);
  if (!joint_) app_.unpack(app_params_);
  const int n = int(anchors.rows());
  const int F = tp_.feature_dim();
  if (!parallel_equal(xs, noted_xs_) || !parallel_equal(ys, noted_ys_) ||
      !parallel_equal(zs, noted_zs_)) {
    // New lookup points (the first decode, or density control changed the anchors): the texels
    // they read join the touched set (which never shrinks: a texel left behind keeps its
    // moments, and Adam keeps moving it as before).
    triplane_mark_texels(tp_, xs.data(), ys.data(), zs.data(), n, &touched_);
    touched_ranges_ = texel_ranges(touched_, tp_.channels);
    noted_xs_ = xs, noted_ys_ = ys, noted_zs_ = zs;
    // The backward's binning of these points, made once for all the steps until they change.
    bins_ = triplane_bins(tp_, xs.data(), ys.data(), zs.data(), n);
    texel0_stale_ = true;  // its taps are made when the texel-space path next runs
  }
  if (subset && last_.size() != size_t(n))
    throw Error("Decoder::decode: a subset needs a whole decode of the same points before it");
  subset_.clear();
  if (subset) subset_ = *subset;
  const int m = subset ? int(subset->size()) : n;
  const float *px = xs.data(), *py = ys.data(), *pz = zs.data();
  if (subset) {
    sub_xs_.resize(size_t(m)), sub_ys_.resize(size_t(m)), sub_zs_.resize(size_t(m));
    for (int j = 0; j < m; ++j) {
      const int i = subset_[size_t(j)];
      if (i < 0 || i >= n) throw Error("Decoder::decode: subset index out of range");
      sub_xs_[size_t(j)] = xs[size_t(i)], sub_ys_[size_t(j)] = ys[size_t(i)];
      sub_zs_[size_t(j)] = zs[size_t(i)];
    }
    px = sub_xs_.data(), py = sub_ys_.data(), pz = sub_zs_.data();
  }
  const Mlp* mlps[2] = {&geo_, &app_};
  const int count = joint_ ? 1 : 2;
  texel0_used_ = !subset && TexelLayer0::available(tp_, mlps, count);
  if (texel0_used_) {
    // The first layers in texel space, then the rest of the MLPs.
    if (texel0_stale_) texel0_.set_points(tp_, touched_, xs.data(), ys.data(), zs.data(), n);
    texel0_stale_ = false;
    mlp_tail_buffers(geo_, m, geo_cache_, Yg_);
    if (!joint_) mlp_tail_buffers(app_, m, app_cache_, Ya_);
    MlpCache* caches[2] = {&geo_cache_, &app_cache_};
    Mlp::Mat* Ys[2] = {&Yg_, &Ya_};
    texel0_.forward(tp_, mlps, count, caches);
    mlp_forward_tail(mlps, caches, Ys, count);
  } else {
    feats_.resize(size_t(m) * F);
    triplane_forward(tp_, px, py, pz, m, feats_.data());
    Eigen::Map<const Mlp::Mat> X(feats_.data(), F, m);
    // The MLPs read the features, which stay in feats_ until the backward: no copy in the caches.
    if (joint_)
      mlp_forward(geo_, X, geo_cache_, Yg_, false);
    else
      mlp_forward_pair(geo_, app_, X, geo_cache_, Yg_, app_cache_, Ya_);
  }
  const int gs = geo_.out_dim();  // a point's outputs in Yg_
  // The outputs go to the last decode's Gaussians (a subset replaces only its own), which are
  // then copied out, so that what the caller's components add to `g` never accumulates.
  last_.sh_degree = 0;
  last_.resize(n);
  last_offsets_.resize(3 * size_t(n));
  tanh_off_.resize(3 * size_t(m));
  scale_ratio_.resize(3 * size_t(m));
  const int sdim = sdim_;
  const float max_offset = opt_.max_offset;
  Gaussians& o = last_;
  float* off = last_offsets_.data();
  const int* sub = subset ? subset_.data() : nullptr;
#pragma omp parallel for schedule(static)
  for (int j = 0; j < m; ++j) {
    const size_t i = size_t(sub ? sub[j] : j);
    const float* y = Yg_.data() + size_t(j) * gs;
    for (int k = 0; k < 3; ++k) {
      const float t = std::tanh(y[k]);
      tanh_off_[3 * size_t(j) + k] = t;
      off[3 * i + k] = max_offset * t;
      o.means[3 * i + k] = float(anchors(long(i), k)) + max_offset * t;
      const float ls = base_log_scale_ + y[3 + (sdim == 1 ? 0 : k)] + log_scale_bias[i];
      o.log_scales[3 * i + k] =
          filtered_log_scale(ls, filter_var_, &scale_ratio_[3 * size_t(j) + k]);
    }
    o.quats[4 * i] = 1.f + y[3 + sdim];
    for (int k = 1; k < 4; ++k) o.quats[4 * i + k] = y[3 + sdim + k];
    o.opacity_logits[i] = init_opacity_logit_ + y[7 + sdim];
    const float* a = joint_ ? y + geo_out_ : Ya_.data() + size_t(j) * 3;
    for (int k = 0; k < 3; ++k) o.sh[3 * i + k] = sh_init_[k] + a[k];
  }
  // Copied over the threads (11 floats and more a Gaussian, about 10 MB at the defaults).
  g.sh_degree = last_.sh_degree;
  for (auto f : {&Gaussians::means, &Gaussians::log_scales, &Gaussians::quats,
                 &Gaussians::opacity_logits, &Gaussians::sh})
    parallel_assign(g.*f, last_.*f);
  parallel_assign(offsets, last_offsets_);
}

void Decoder::backward(const std::vector<float>& xs, const std::vector<float>& ys,
                       const std::vector<float>& zs, const std::vector<float>& dmeans,
                       const std::vector<float>& doff, const std::vector<float>& dls,
                       const std::vector<float>& dquats, const std::vector<float>& dopacity,
                       const std::vector<float>& dsh) {
  // The last decode's points: all of them, or its subset (whose gradients are gathered).
  const int m = int(tanh_off_.size() / 3);
  const int* sub = subset_.empty() ? nullptr : subset_.data();
  const int sdim = sdim_;
  const float max_offset = opt_.max_offset;
  const int gs = geo_.out_dim();
  dYg_.resize(gs, m);
  if (!joint_) dYa_.resize(3, m);
#pragma omp parallel for schedule(static)
  for (int j = 0; j < m; ++j) {
    const size_t i = size_t(sub ? sub[j] : j);
    float* y = dYg_.data() + size_t(j) * gs;
    const float* sr = &scale_ratio_[3 * size_t(j)];
    for (int k = 0; k < 3; ++k) {
      const float t = tanh_off_[3 * size_t(j) + k];
      y[k] = (dmeans[3 * i + k] + doff[3 * i + k]) * max_offset * (1.f - t * t);
    }
    if (sdim == 1)
      y[3] = dls[3 * i] * sr[0] + dls[3 * i + 1] * sr[1] + dls[3 * i + 2] * sr[2];
    else
      for (int k = 0; k < 3; ++k) y[3 + k] = dls[3 * i + k] * sr[k];
    for (int k = 0; k < 4; ++k) y[3 + sdim + k] = dquats[4 * i + k];
    y[7 + sdim] = dopacity[i];
    float* a = joint_ ? y + geo_out_ : dYa_.data() + size_t(j) * 3;
    for (int k = 0; k < 3; ++k) a[k] = dsh[3 * i + k];
  }
  ggeo_.zero_like(geo_);
  if (texel0_used_) {
    if (!parallel_equal(xs, noted_xs_) || !parallel_equal(ys, noted_ys_) ||
        !parallel_equal(zs, noted_zs_))
      throw Error("Decoder::backward: the points differ from the last decode's");
    if (!joint_) gapp_.zero_like(app_);
    const Mlp* mlps[2] = {&geo_, &app_};
    const MlpCache* caches[2] = {&geo_cache_, &app_cache_};
    const Mlp::Mat* dYs[2] = {&dYg_, &dYa_};
    MlpGrads* grads[2] = {&ggeo_, &gapp_};
    const int count = joint_ ? 1 : 2;
    const int H = TexelLayer0::width(mlps, count);
    d0_.resize(size_t(H) * size_t(m));
    float* d0s[2] = {d0_.data(), d0_.data() + geo_.W[0].rows()};
    mlp_backward_tail(mlps, caches, dYs, grads, d0s, H, count);
    // Writes every touched texel's gradient (no zeroing needed).
    texel0_.backward(tp_, mlps, count, d0_.data(), grads, dplanes_.data());
    ggeo_.pack(geo_grad_);
    if (!joint_) gapp_.pack(app_grad_);
    return;
  }
  if (joint_) {
    mlp_backward(geo_, geo_cache_, dYg_, ggeo_, &dX_, feats_.data());
  } else {
    gapp_.zero_like(app_);
    // Both MLPs read the same features: the appearance MLP's input gradient is added to the
    // geometry MLP's.
    mlp_backward_pair(geo_, geo_cache_, dYg_, ggeo_, app_, app_cache_, dYa_, gapp_, dX_,
                      feats_.data());
  }
  // Only texels of the touched set are ever written (the points are the last decode's).
  if (!parallel_equal(xs, noted_xs_) || !parallel_equal(ys, noted_ys_) ||
      !parallel_equal(zs, noted_zs_))
    throw Error("Decoder::backward: the points differ from the last decode's");
  const auto& R = touched_ranges_;
#pragma omp parallel for schedule(dynamic, 16)
  for (long r = 0; r < long(R.size()); ++r)
    std::fill(dplanes_.begin() + long(R[size_t(r)].first),
              dplanes_.begin() + long(R[size_t(r)].second), 0.f);
  if (sub)
    triplane_backward(tp_, sub_xs_.data(), sub_ys_.data(), sub_zs_.data(), m, dX_.data(),
                      dplanes_.data());
  else
    triplane_backward(tp_, xs.data(), ys.data(), zs.data(), m, dX_.data(), dplanes_.data(), &bins_);
  ggeo_.pack(geo_grad_);
  if (!joint_) gapp_.pack(app_grad_);
}

}  // namespace ks
