// `track`'s temporal terms (track/temporal_terms.hpp): the Jacobians against central differences
// through their own forward, zero acceleration for a body moving at constant velocity on uneven
// steps; and the temporal solve (track/temporal.hpp) on a walk seen by a fixed camera with exact
// keypoints: a frame whose legs' labels are exchanged is found and set right, a frame with its
// wrist and elbow missing is placed by its neighbours, a frame started in a wrong pose is
// restarted from them; off, nothing changes.
#include <gtest/gtest.h>

#include <random>

#include "body/body_model.hpp"
#include "body/joints.hpp"
#include "body/keypoints.hpp"
#include "core/error.hpp"
#include "core/rotation.hpp"
#include "fit/evaluator.hpp"
#include "fit/fit.hpp"
#include "fit/fit_body.hpp"
#include "motion/motion.hpp"
#include "track/temporal.hpp"
#include "track/temporal_terms.hpp"

namespace ks {

namespace {

namespace sj = smpl_joint;

Eigen::VectorXd random_x(const fit::Layout& L, std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 0.3);
  Eigen::VectorXd x(L.size);
  for (int i = 0; i < L.size; ++i) x(i) = n(rng);
  x.segment<3>(L.cam) = Eigen::Vector3d(n(rng), n(rng), 3.0 + n(rng));
  return x;
}

// Each block's Jacobian against central differences of the residuals (every frame's evaluator
// recomputed at each point, as Ceres does through the SequenceEvaluator).
void expect_blocks_match(const ceres::CostFunction& f, track::SequenceEvaluator& seq,
                         std::vector<Eigen::VectorXd*> xs) {
  const int n = f.num_residuals();
  const size_t N = size_t(n);
  std::vector<const double*> params;
  for (auto* x : xs) params.push_back(x->data());
  std::vector<std::vector<double>> J(xs.size());
  std::vector<double*> jac;
  for (size_t b = 0; b < xs.size(); ++b) {
    J[b].resize(N * size_t(xs[b]->size()));
    jac.push_back(J[b].data());
  }
  std::vector<double> r(N), rp(N), rm(N);
  seq.PrepareForEvaluation(true, true);
  ASSERT_TRUE(f.Evaluate(params.data(), r.data(), jac.data()));
  const double h = 1e-6;
  double largest = 0;
  for (size_t b = 0; b < xs.size(); ++b) {
    Eigen::VectorXd& x = *xs[b];
    for (int c = 0; c < x.size(); ++c) {
      const double x0 = x(c);
      x(c) = x0 + h;
      seq.PrepareForEvaluation(false, true);
      ASSERT_TRUE(f.Evaluate(params.data(), rp.data(), nullptr));
      x(c) = x0 - h;
      seq.PrepareForEvaluation(false, true);
      ASSERT_TRUE(f.Evaluate(params.data(), rm.data(), nullptr));
      x(c) = x0;
      for (int i = 0; i < n; ++i) {
        const double fd = (rp[size_t(i)] - rm[size_t(i)]) / (2 * h);
        const double an = J[b][size_t(i) * size_t(x.size()) + size_t(c)];
        EXPECT_NEAR(an, fd, 1e-5 * std::max(1.0, std::abs(fd)))
            << "block " << b << ", residual " << i << ", param " << c;
        largest = std::max(largest, std::abs(an));
      }
    }
  }
  EXPECT_GT(largest, 1.0);  // the term depends on the parameters at all
}

}  // namespace

TEST(TemporalTerms, JacobiansMatchFiniteDifferences) {
  const fit::BodyData d =
      fit::make_body_data(default_body_model(), 10, 13, KeypointConvention::kCoco);
  const fit::Layout& L = d.layout;
  std::mt19937 rng(5);
  Eigen::VectorXd x0 = random_x(L, rng), x1 = random_x(L, rng), x2 = random_x(L, rng);
  fit::Evaluator e0(d, x0.data(), false), e1(d, x1.data(), false), e2(d, x2.data(), false);
  track::SequenceEvaluator seq({&e0, &e1, &e2});
  EXPECT_EQ(track::temporal_point_count(22), 22 + kBody25Count);
  for (int q : {0, 7, 21, 22 + body25::kLHeel, 22 + body25::kNose}) {
    std::unique_ptr<ceres::CostFunction> acc(
        track::acceleration_residual(&e0, &e1, &e2, 0.0, 0.04, 0.1, 6.0, L.size, L.cam, 22, q));
    EXPECT_EQ(acc->num_residuals(), 3);
    expect_blocks_match(*acc, seq, {&x0, &x1, &x2});
    std::unique_ptr<ceres::CostFunction> vel(
        track::velocity_residual(&e0, &e1, 0.0, 0.04, 0.5, L.size, L.cam, 22, q));
    expect_blocks_match(*vel, seq, {&x0, &x1});
  }
  EXPECT_THROW(track::acceleration_residual(&e0, &e1, &e2, 0.0, 0.04, 0.1, 6.0, L.size, L.cam, 22,
                                            22 + kBody25Count),
               Error);
}

// One pose moving at constant velocity, on uneven steps: no acceleration; a jump in the middle
// frame: the residual in units of the prior's deviation.
TEST(TemporalTerms, ConstantVelocityHasNoAcceleration) {
  const fit::BodyData d =
      fit::make_body_data(default_body_model(), 10, 13, KeypointConvention::kCoco);
  const fit::Layout& L = d.layout;
  std::mt19937 rng(9);
  const Eigen::VectorXd base = random_x(L, rng);
  const Eigen::Vector3d v(0.4, -0.1, 0.8);  // m/s
  const double t[3] = {0.0, 0.05, 0.15};
  Eigen::VectorXd x[3];
  for (int i = 0; i < 3; ++i) {
    x[i] = base;
    x[i].segment<3>(L.cam) += t[i] * v;
  }
  fit::Evaluator e0(d, x[0].data(), false), e1(d, x[1].data(), false), e2(d, x[2].data(), false);
  track::SequenceEvaluator seq({&e0, &e1, &e2});
  seq.PrepareForEvaluation(false, true);
  const double* p[] = {x[0].data(), x[1].data(), x[2].data()};
  const double expect = -(1 / 0.05 + 1 / 0.1) * 0.01 / (2.0 * std::sqrt(0.15 / 3.0));
  for (int q : {0, 15, 30}) {
    std::unique_ptr<ceres::CostFunction> acc(
        track::acceleration_residual(&e0, &e1, &e2, t[0], t[1], t[2], 2.0, L.size, L.cam, 22, q));
    double r[3];
    x[1](L.cam) = base(L.cam) + t[1] * v.x();
    seq.PrepareForEvaluation(false, true);
    ASSERT_TRUE(acc->Evaluate(p, r, nullptr));
    for (double e : r) EXPECT_NEAR(e, 0.0, 1e-9) << "point " << q;
    // The middle frame 1 cm off in x: the x residual is -(1/h0 + 1/h1) 0.01 / deviation.
    x[1](L.cam) += 0.01;
    seq.PrepareForEvaluation(false, true);
    ASSERT_TRUE(acc->Evaluate(p, r, nullptr));
    EXPECT_NEAR(r[0], expect, 1e-9) << "point " << q;
    EXPECT_NEAR(r[1], 0.0, 1e-9);
  }
  EXPECT_THROW(
      track::acceleration_residual(&e0, &e1, &e2, 0.0, 0.0, 0.1, 2.0, L.size, L.cam, 22, 0), Error);
}

namespace {

// A walk towards a fixed camera, 9 frames at 30 fps, with every BODY_25 point (the joints'
// convention) projected exactly; the fits start near the truth.
struct Walk {
  const BodyModel& model = default_body_model();
  fit::BodyData d = fit::make_body_data(model, 10, 6, KeypointConvention::kJoints);
  FitOptions fo;
  std::vector<Eigen::VectorXd> truth;
  std::vector<FitInput> inputs;
  std::vector<double> times;
  std::vector<FitResult> fits;
  Walk() {
    fo.keypoints = KeypointConvention::kJoints;
    fo.focal = 900;
    const fit::Layout& L = d.layout;
    const Motion m = builtin_motion("walk", 64);
    const Eigen::Vector3d tc(0.0, 0.2, 6.0);
    std::mt19937 rng(3);
    std::normal_distribution<double> n(0.0, 1.0);
    for (int f = 0; f < 9; ++f) {
      BodyParams p = m.frames[size_t(20 + f)];
      p.betas = Eigen::VectorXd::Zero(10);
      const Eigen::Vector3d t = fit::camera_rotation() * p.transl + tc;
      p.transl.setZero();
      const Eigen::VectorXd x = fit::pack(L, p, t);
      truth.push_back(x);
      times.push_back((20 + f) / m.fps);
      std::vector<Eigen::Vector3d> J, V, K;
      fit::forward<double>(d, x.data(), J, &V, nullptr, &K);
      FitInput in;
      in.width = 640;
      in.height = 640;
      for (int k = 0; k < kBody25Count; ++k) {
        const Eigen::Vector3d c = fit::to_camera(K[size_t(k)], t);
        in.keypoints[size_t(k)] =
            Eigen::Vector3d(fo.focal * c.x() / c.z() + 320, fo.focal * c.y() / c.z() + 320, 1.0);
      }
      inputs.push_back(in);
      FitResult fr;
      Eigen::VectorXd y = x;
      for (int i = 0; i < L.cam; ++i)
        if (i < L.betas || i >= L.betas + L.num_betas) y(i) += 0.04 * n(rng);
      for (int k = 0; k < 3; ++k) y(L.cam + k) += 0.02 * n(rng);
      fr.params = fit::unpack_params(L, y);
      fr.camera = fit_camera(fo, in.width, in.height, fit::unpack_cam(L, y));
      fits.push_back(fr);
    }
  }
  // The largest joint error (m) of frame f's fit, in the camera's frame.
  double joint_error(int f, int joint = -1) const {
    const fit::Layout& L = d.layout;
    BodyParams p = fits[size_t(f)].params;
    p.betas = Eigen::VectorXd::Zero(10);
    const Eigen::VectorXd x = fit::pack(L, p, fits[size_t(f)].camera.t);
    std::vector<Eigen::Vector3d> Je, Jt;
    fit::forward<double>(d, x.data(), Je, nullptr);
    fit::forward<double>(d, truth[size_t(f)].data(), Jt, nullptr);
    double e = 0;
    for (int j = 0; j < 22; ++j)
      if (joint < 0 || j == joint)
        e = std::max(
            e, (fit::to_camera(Je[size_t(j)], Eigen::Vector3d(x.segment<3>(L.cam))) -
                fit::to_camera(Jt[size_t(j)], Eigen::Vector3d(truth[size_t(f)].segment<3>(L.cam))))
                   .norm());
    return e;
  }
};

}  // namespace

// Each frame's largest joint error (m) after the temporal solve of the clean walk: what the
// keypoints leave open in depth, the reference the failures below must come back to.
std::vector<double> clean_errors(double* left_wrist_6 = nullptr) {
  Walk w;
  solve_temporal(w.model, w.inputs, w.times, Eigen::VectorXd::Zero(10), w.fits, w.fo, {});
  std::vector<double> e;
  for (int f = 0; f < 9; ++f) e.push_back(w.joint_error(f));
  if (left_wrist_6) *left_wrist_6 = w.joint_error(6, sj::kLeftWrist);
  return e;
}

TEST(TemporalSolve, ExchangedLabelsAreFoundAndDropoutsFilled) {
  double clean_wrist = 0;
  const std::vector<double> clean = clean_errors(&clean_wrist);
  using namespace body25;
  for (bool fix : {true, false}) {
    Walk w;
    const auto given = w.inputs;
    // Frame 4: the detector read the legs the other way round. Frame 6: no left elbow or wrist.
    for (int k : {kRHip, kRKnee, kRAnkle, kRBigToe, kRSmallToe, kRHeel})
      std::swap(w.inputs[4].keypoints[size_t(k)], w.inputs[4].keypoints[size_t(body25_mirror(k))]);
    w.inputs[6].keypoints[kLElbow].setZero();
    w.inputs[6].keypoints[kLWrist].setZero();
    const Eigen::VectorXd betas = Eigen::VectorXd::Zero(10);
    TemporalOptions to;
    to.fix_swaps = fix;
    const TemporalReport rep = solve_temporal(w.model, w.inputs, w.times, betas, w.fits, w.fo, to);
    ASSERT_TRUE(rep.applied);
    if (!fix) {  // without the fix frame 4's keypoints stay unexplained (the robust loss and
                 // the neighbours hold its body)
      EXPECT_TRUE(rep.swapped.empty());
      EXPECT_GT(w.fits[4].costs.at("keypoints"), 10 * w.fits[3].costs.at("keypoints"));
      continue;
    }
    EXPECT_EQ(rep.swapped, std::vector<int>{4});
    EXPECT_LT(rep.cost_after, rep.cost_before);
    for (int k = 0; k < kBody25Count; ++k)
      EXPECT_EQ(w.inputs[4].keypoints[size_t(k)], given[4].keypoints[size_t(k)])
          << "keypoint " << k;
    for (int f = 0; f < 9; ++f)
      EXPECT_LT(w.joint_error(f), clean[size_t(f)] + 0.02) << "frame " << f;
    EXPECT_LT(w.joint_error(6, sj::kLeftWrist), clean_wrist + 0.02);
    EXPECT_LT(w.fits[4].costs.at("keypoints"), 3 * w.fits[3].costs.at("keypoints") + 1e-3);
    for (const FitResult& f : w.fits) {
      EXPECT_GT(f.costs.at("total"), 0.0);
      EXPECT_EQ(f.params.betas, betas);
    }
  }
}

TEST(TemporalSolve, AFrameStartedTurnedAroundComesBack) {
  const std::vector<double> clean = clean_errors();
  Walk w;
  // Frame 3 starts turned half round (the single-photo fit's front / back confusion).
  const Eigen::Matrix3d R = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                            axis_angle_to_matrix(Eigen::Vector3d(w.fits[3].params.global_orient));
  w.fits[3].params.global_orient = matrix_to_axis_angle(R);
  const TemporalReport rep =
      solve_temporal(w.model, w.inputs, w.times, Eigen::VectorXd::Zero(10), w.fits, w.fo, {});
  ASSERT_TRUE(rep.applied);
  for (int f = 0; f < 9; ++f) EXPECT_LT(w.joint_error(f), clean[size_t(f)] + 0.02) << "frame " << f;
}

TEST(TemporalSolve, OffOrTooShortChangesNothing) {
  Walk w;
  const auto before = w.fits;
  TemporalOptions off;
  off.enabled = false;
  EXPECT_FALSE(
      solve_temporal(w.model, w.inputs, w.times, Eigen::VectorXd::Zero(10), w.fits, w.fo, off)
          .applied);
  std::vector<FitInput> two(w.inputs.begin(), w.inputs.begin() + 2);
  std::vector<double> t2(w.times.begin(), w.times.begin() + 2);
  std::vector<FitResult> f2(w.fits.begin(), w.fits.begin() + 2);
  EXPECT_FALSE(solve_temporal(w.model, two, t2, Eigen::VectorXd::Zero(10), f2, w.fo, {}).applied);
  for (size_t f = 0; f < before.size(); ++f)
    EXPECT_EQ(w.fits[f].params.body_pose, before[f].params.body_pose);
  std::vector<double> back = w.times;
  std::swap(back[2], back[3]);
  EXPECT_THROW(solve_temporal(w.model, w.inputs, back, Eigen::VectorXd::Zero(10), w.fits, w.fo, {}),
               Error);
}

}  // namespace ks
