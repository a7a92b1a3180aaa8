// End-to-end check of the avatar fit on tiny in-memory data: targets rendered from a coloured
// Gaussian body in two poses; a short fit must improve the training PSNR well above the start
// and produce a consistent avatar.
#include "reconstruct/trainer.hpp"
#include "reconstruct/decoder.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "evaluate/metrics.hpp"
#include "raster/rasterizer.hpp"
#include "reconstruct/density_ops.hpp"
#include "reconstruct/tiny_avatar.hpp"

namespace ks {

namespace {

std::vector<LoadedFrame> make_frames(const BodyModel& model, const Dataset& ds, const Avatar& truth,
                                     int n_frames, double shoulder = 0.3) {
  std::vector<LoadedFrame> frames;
  RasterSettings rs;
  for (int k = 0; k < 3; ++k) rs.background[k] = ds.background[k];
  for (int f = 0; f < n_frames; ++f) {
    LoadedFrame t;
    t.pose.betas = ds.betas;
    t.pose.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
    t.pose.global_orient = Eigen::Vector3d(0, 2.0 * M_PI * f / n_frames, 0);
    t.pose.body_pose[3 * 15 + 2] = shoulder * (f % 2);  // left shoulder
    t.camera = Camera::look_at_fov({0, 0, 3.2}, {0, -0.3, 0}, 40, 56, 45.0);
    Gaussians posed = pose_avatar(truth, t.pose);
    RasterResult rr;
    rasterize_forward(posed, t.camera, rs, rr);
    t.image = rr.color;
    t.mask = rr.alpha;
    frames.push_back(std::move(t));
  }
  return frames;
}

// PSNR of the avatar posed and rendered as the frame (on the dataset's background).
double frame_psnr(const Avatar& a, const Dataset& ds, const LoadedFrame& fr) {
  RasterSettings rs;
  for (int k = 0; k < 3; ++k) rs.background[k] = ds.background[k];
  RasterResult r;
  rasterize_forward(pose_avatar(a, fr.pose), fr.camera, rs, r);
  return psnr(r.color, fr.image);
}

}  // namespace

TEST(Trainer, FitsTinyRenderedPerson) {
  const BodyModel& model = default_body_model();
  Dataset ds;
  ds.betas = Eigen::VectorXd::Zero(model.num_betas);
  TrainOptions opt = test::tiny_train_options(32, 8, 32);
  opt.iterations = 60;
  opt.visibility.enabled = true;
  opt.visibility.cell = 1;  // 40 x 56 frames: pixel cells, so that the back is hidden
  // The "truth": a short fit's own structure with colours painted by height.
  Avatar truth = test::one_step_avatar(model, ds, opt);
  test::paint_by_height(truth, 4.f, -0.8f, 3.f);
  const auto frames = make_frames(model, ds, truth, 4);
  TrainReport rep;
  opt.iterations = 1;
  Avatar a0 = train_avatar(model, ds, frames, opt, &rep);
  opt.iterations = 50;
  Avatar a1 = train_avatar(model, ds, frames, opt, &rep);
  EXPECT_EQ(a1.num_gaussians(), model.num_vertices());
  EXPECT_NO_THROW(a1.validate());
  // Render both from frame 1 and compare to the target.
  const double p0 = frame_psnr(a0, ds, frames[1]), p1 = frame_psnr(a1, ds, frames[1]);
  EXPECT_GT(p1, p0 + 3.0) << "start " << p0 << " dB, after " << p1 << " dB";
  // From iteration 5 on (visibility's start, 0.1) the steps decoded only what their frame sees.
  EXPECT_EQ(rep.visible_steps, 45);
  EXPECT_LT(rep.visible_share, 0.9);
  EXPECT_GT(rep.visible_share, 0.3);
  // Deterministic under the seed up to the summation order of the rasterizer's threaded
  // backward pass (bit-identical with one thread).
  Avatar a2 = train_avatar(model, ds, frames, opt);
  ASSERT_EQ(a1.gaussians.sh.size(), a2.gaussians.sh.size());
  for (size_t i = 0; i < a1.gaussians.sh.size(); i += 97)
    EXPECT_NEAR(a1.gaussians.sh[i], a2.gaussians.sh[i], 2e-2);
}

// The per-Gaussian colour residual (vertex_color.lr > 0) fits colour detail finer than the
// triplane's cells, and follows density control when it changes the vertex set.
TEST(Trainer, VertexColourResidualFitsFineDetailThroughDensityControl) {
  const BodyModel& model = default_body_model();
  Dataset ds;
  ds.betas = Eigen::VectorXd::Zero(model.num_betas);
  // An 8x8 triplane (cells of ~25 cm): no stripe detail from the triplane.
  TrainOptions opt = test::tiny_train_options(8, 4, 16);
  Avatar truth = test::one_step_avatar(model, ds, opt);
  for (int i = 0; i < truth.num_gaussians(); ++i) {
    const float y = truth.gaussians.means[3 * size_t(i) + 1];
    const float stripe = std::sin(60.f * y) > 0 ? 1.2f : -1.2f;  // ~10 cm stripes
    for (int k = 0; k < 3; ++k) truth.gaussians.sh[3 * size_t(i) + k] = stripe;
    truth.gaussians.opacity_logits[i] = 4.f;
  }
  const auto frames = make_frames(model, ds, truth, 4);
  auto fit_psnr = [&](float lr_vc, DensityControl* dc, int* count) {
    TrainOptions o = opt;
    o.iterations = 30;
    o.vertex_color.lr = lr_vc;
    o.density_control = dc;
    Avatar a = train_avatar(model, ds, frames, o);
    EXPECT_NO_THROW(a.validate());
    *count = a.num_gaussians();
    return frame_psnr(a, ds, frames[1]);
  };
  int n_off = 0, n_on = 0, n_dc = 0;
  const double p_off = fit_psnr(0.f, nullptr, &n_off);
  const double p_on = fit_psnr(0.05f, nullptr, &n_on);
  EXPECT_EQ(n_off, n_on);
  EXPECT_GT(p_on, p_off + 1.0) << "without " << p_off << " dB, with " << p_on << " dB";
  // Density control splits faces during the fit: the residuals are carried to the new vertices.
  DensityOptions dopt;
  dopt.image_width = 40;
  dopt.start = 8;  // one split round at iteration 8, around every vertex that was seen
  dopt.stop = 9;
  dopt.interval = 1;
  dopt.grad_threshold = 1e-9f;
  auto dc = make_density_control("vertex", dopt);
  const double p_dc = fit_psnr(0.05f, dc.get(), &n_dc);
  EXPECT_GT(n_dc, n_on);
  EXPECT_GT(p_dc, p_off + 1.0) << "with density control " << p_dc << " dB";
}

// Learned skin weights (skin.lr > 0, regularisers off): the truth keeps the left upper arm on the
// left collar while the shoulder turns, which the body's weights cannot follow; the learned
// weights move towards the collar (the body gives it ~0.16 there).
TEST(Trainer, LearnedSkinWeightsFollowSkinningTheBodyCannot) {
  const BodyModel& model = default_body_model();
  Dataset ds;
  ds.betas = Eigen::VectorXd::Zero(model.num_betas);
  TrainOptions opt = test::tiny_train_options(32, 8, 32);
  Avatar truth = test::one_step_avatar(model, ds, opt);
  const int collar = 13;
  int moved = 0;
  test::paint_by_height(truth, 8.f, -0.5f, 6.f);
  for (int i = 0; i < truth.num_gaussians(); ++i) {
    if (truth.part_labels[size_t(i)] == kLeftUpperArm) {
      for (int k = 0; k < 4; ++k) {
        truth.skin_joints[4 * size_t(i) + k] = k == 0 ? collar : 0;
        truth.skin_weights[4 * size_t(i) + k] = k == 0 ? 1.f : 0.f;
      }
      ++moved;
    }
  }
  ASSERT_GT(moved, 100);
  const auto frames = make_frames(model, ds, truth, 4, 0.25);
  auto fit = [&](float lr_skin, Avatar* out) {
    TrainOptions o = opt;
    o.iterations = 60;
    o.skin.lr = lr_skin;
    o.skin.w_prior = 0.f;
    o.skin.w_laplacian = 0.f;
    Avatar a = train_avatar(model, ds, frames, o);
    EXPECT_NO_THROW(a.validate());
    const double p = frame_psnr(a, ds, frames[1]);
    if (out) *out = std::move(a);
    return p;
  };
  Avatar learned;
  const double p_fixed = fit(0.f, nullptr), p_learned = fit(0.2f, &learned);
  // The misfit is a pixel or two on a small part of a 40x56 frame: the weights are the signal.
  EXPECT_GT(p_learned, p_fixed - 0.1)
      << "fixed " << p_fixed << " dB, learned " << p_learned << " dB";
  // The baked top-4 weights moved towards the collar on the upper arm.
  double collar_w = 0;
  int count = 0;
  for (int i = 0; i < learned.num_gaussians(); ++i) {
    if (learned.part_labels[size_t(i)] != kLeftUpperArm) continue;
    for (int k = 0; k < 4; ++k)
      if (learned.skin_joints[4 * size_t(i) + k] == collar)
        collar_w += learned.skin_weights[4 * size_t(i) + k];
    ++count;
  }
  EXPECT_GT(collar_w / count, 0.3) << "mean collar weight on the left upper arm";
}

TEST(Trainer, RejectsBadOptions) {
  const BodyModel& model = default_body_model();
  Dataset ds;
  TrainOptions opt;
  EXPECT_THROW(train_avatar(model, ds, {}, opt), Error);
  PerturbOptions p;
  EXPECT_THROW(load_frames(ds, "/nonexistent", 0.f, p, 0), Error);
  // Coarse-to-fine needs the same frames at both resolutions.
  std::vector<LoadedFrame> one(1), none;
  one[0].image = Image(8, 8, 3, 1.f);
  one[0].mask = Image(8, 8, 1, 0.f);
  one[0].camera = Camera::look_at_fov({0, 0, 3.2}, {0, -0.3, 0}, 8, 8, 45.0);
  opt.iterations = 1;
  opt.subdivide = 0;
  opt.progress = false;
  opt.fine_frames = &none;
  opt.fine_from = 0.5f;
  EXPECT_THROW(train_avatar(model, ds, one, opt), Error);
  opt.fine_frames = nullptr;
  opt.visibility.start = 1.5f;
  EXPECT_THROW(train_avatar(model, ds, one, opt), Error);
  opt.visibility.start = 0.1f;
  opt.visibility.depth_margin = -0.01f;
  EXPECT_THROW(train_avatar(model, ds, one, opt), Error);
  opt.visibility.depth_margin = 0.03f;
  opt.visibility.whole_every = -1;
  EXPECT_THROW(train_avatar(model, ds, one, opt), Error);
}

}  // namespace ks

namespace ks {
namespace {

TEST(Trainer, FilteredLogScaleGradientMatchesFiniteDifferences) {
  const double var = 2.5e-5;  // (5 mm)^2
  for (double ls : {-8.0, -6.0, -5.3, -4.0, -2.0}) {
    double d = 0;
    const double y = filtered_log_scale(ls, var, &d);
    EXPECT_NEAR(y, 0.5 * std::log(std::exp(2 * ls) + var), 1e-12);
    EXPECT_GE(y, ls);                           // never thinner than unfiltered
    EXPECT_GE(y, 0.5 * std::log(var) - 1e-12);  // never thinner than the filter
    const double h = 1e-6;
    double dd;
    const double fd =
        (filtered_log_scale(ls + h, var, &dd) - filtered_log_scale(ls - h, var, &dd)) / (2 * h);
    EXPECT_NEAR(d, fd, 1e-7) << "ls " << ls;
  }
  double d = 0;
  EXPECT_EQ(filtered_log_scale(-3.0, 0.0, &d), -3.0);  // off
  EXPECT_EQ(d, 1.0);
}

}  // namespace
}  // namespace ks
