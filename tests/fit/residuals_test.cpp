// Each term of the fit's objective (fit/residuals.hpp): its Jacobian, as Ceres reads it, against
// central differences of its own residuals (the shared Evaluator recomputed at each point, as
// Ceres does); the camera's fixed rotation; the stage schedule as data.
#include <gtest/gtest.h>

#include <random>

#include "body/joints.hpp"
#include "body/keypoints.hpp"
#include "fit/evaluator.hpp"
#include "fit/fit.hpp"
#include "fit/fit_body.hpp"
#include "fit/pose_prior.hpp"
#include "fit/residuals.hpp"
#include "fit/silhouette.hpp"

namespace ks {

namespace {

namespace sj = smpl_joint;

struct Scene {
  const BodyModel& model = default_body_model();
  fit::BodyData d = fit::make_body_data(model, 10, 13, KeypointConvention::kCoco);
  Eigen::VectorXd x;
  fit::Projector pr;
  Scene() {
    std::mt19937 rng(11);
    std::normal_distribution<double> n(0.0, 0.3);
    BodyParams p;
    p.global_orient = Eigen::Vector3d(n(rng), n(rng), n(rng));
    p.body_pose = Eigen::VectorXd(3 * d.layout.pose_joints);
    for (long i = 0; i < p.body_pose.size(); ++i) p.body_pose(i) = n(rng);
    p.betas = Eigen::VectorXd(d.layout.num_betas);
    for (long i = 0; i < p.betas.size(); ++i) p.betas(i) = 3 * n(rng);
    x = fit::pack(d.layout, p, Eigen::Vector3d(0.05, 0.3, 3.0));
    pr.f = 600;
    pr.cx = 128;
    pr.cy = 192;
    pr.cam = d.layout.cam;
  }
  int P() const { return d.layout.size; }
};

// The block's Jacobian at x against central differences of its residuals; returns the largest
// |entry| of the Jacobian (so a test can tell that the term depends on the parameters at all).
double expect_jacobian_matches(const ceres::CostFunction& f, fit::Evaluator* ev, Eigen::VectorXd& x,
                               double h = 1e-6, double tol = 1e-5) {
  const int n = f.num_residuals(), P = int(x.size());
  const size_t N = static_cast<size_t>(n);
  std::vector<double> r(N), J(N * static_cast<size_t>(P)), rp(N), rm(N);
  const double* params[] = {x.data()};
  double* jac[] = {J.data()};
  if (ev) ev->PrepareForEvaluation(true, true);
  EXPECT_TRUE(f.Evaluate(params, r.data(), jac));
  double largest = 0;
  for (int c = 0; c < P; ++c) {
    const double x0 = x(c);
    x(c) = x0 + h;
    if (ev) ev->PrepareForEvaluation(false, true);
    EXPECT_TRUE(f.Evaluate(params, rp.data(), nullptr));
    x(c) = x0 - h;
    if (ev) ev->PrepareForEvaluation(false, true);
    EXPECT_TRUE(f.Evaluate(params, rm.data(), nullptr));
    x(c) = x0;
    for (int i = 0; i < n; ++i) {
      const double fd = (rp[size_t(i)] - rm[size_t(i)]) / (2 * h);
      const double an = J[size_t(i) * size_t(P) + size_t(c)];
      EXPECT_NEAR(an, fd, tol * std::max(1.0, std::abs(fd))) << "residual " << i << ", param " << c;
      largest = std::max(largest, std::abs(an));
    }
  }
  return largest;
}

}  // namespace

TEST(FitResiduals, KeypointJacobianMatchesFiniteDifferences) {
  Scene s;
  fit::Evaluator ev(s.d, s.x.data(), false);
  for (int k : {int(body25::kNose), int(body25::kRWrist), int(body25::kLHeel)}) {
    const fit::KeypointResidual r(ev, s.pr, k, {100.0, 150.0}, 3.84, s.P());
    EXPECT_GT(expect_jacobian_matches(r, &ev, s.x), 0.0) << "keypoint " << k;
  }
}

TEST(FitResiduals, SilhouetteInsideAndCoverJacobiansMatchFiniteDifferences) {
  Scene s;
  Image mask(256, 384, 1, 0.f);  // a narrow upright box: most of the body projects outside it
  for (int y = 40; y < 360; ++y)
    for (int x = 120; x < 136; ++x) mask.at(x, y, 0) = 1.f;
  const fit::DistanceField df = fit::outside_distance(mask);
  fit::Evaluator ev(s.d, s.x.data(), true);
  int outside = 0;
  for (int m = 0; m < int(s.d.vertex_ids.size()); m += 97) {
    const fit::InsideResidual r(ev, s.pr, df, m, 3.84, s.P());
    if (expect_jacobian_matches(r, &ev, s.x, 1e-7, 1e-4) > 0) ++outside;
  }
  EXPECT_GT(outside, 0);
  const fit::CoverResidual c(ev, s.pr, 5, {20.0, 30.0}, 2.0, 3.84, s.P());
  EXPECT_GT(expect_jacobian_matches(c, &ev, s.x), 0.0);
}

TEST(FitResiduals, PriorJacobiansMatchFiniteDifferences) {
  Scene s;
  auto priors = fit::make_joint_priors(s.d, 70.0, 20.0);
  ASSERT_EQ(int(priors.size()), s.d.layout.pose_joints);
  const int j = sj::kLeftElbow;
  fit::JointPrior jp = priors[size_t(j - 1)];
  jp.w_stance = 4.0;
  const int off = s.d.layout.pose + 3 * (j - 1);
  EXPECT_GT(expect_jacobian_matches(fit::PoseResidual(jp, off, s.P()), nullptr, s.x), 0.0);
  s.x(off + 1) = jp.lo(1) - 0.2;  // beyond the elbow's limit: the limit term is on
  EXPECT_GT(expect_jacobian_matches(fit::LimitResidual(jp, off, s.P()), nullptr, s.x), 0.0);
  EXPECT_GT(expect_jacobian_matches(fit::UprightResidual(0, 0.35, 4.0, s.P()), nullptr, s.x), 0.0);
  const fit::ShapeResidual shape(s.d.layout.betas, s.d.layout.num_betas, 0.3, s.P());
  EXPECT_EQ(shape.num_residuals(), s.d.layout.num_betas);
  EXPECT_GT(expect_jacobian_matches(shape, nullptr, s.x), 0.0);
}

TEST(FitResiduals, GroundAndArmTorsoJacobiansMatchFiniteDifferences) {
  Scene s;
  fit::Evaluator ev(s.d, s.x.data(), false);
  const fit::GroundResidual g(ev, sj::kLeftAnkle, sj::kRightAnkle, s.P());
  EXPECT_GT(expect_jacobian_matches(g, &ev, s.x), 0.0);
  // A capsule wide enough that the wrist is inside it: the term is on.
  const fit::ArmTorsoResidual a(ev, sj::kLeftWrist, 2.0, 20.0, s.P());
  EXPECT_GT(expect_jacobian_matches(a, &ev, s.x), 0.0);
}

TEST(FitResiduals, ToCameraIsTheCameraRotation) {
  const Eigen::Vector3d X(0.3, -1.2, 0.7), t(0.1, 0.2, 3.0);
  EXPECT_EQ(fit::to_camera(X, t), Eigen::Vector3d(fit::camera_rotation() * X + t));
}

TEST(FitSchedule, DefaultIsTorsoPoseFlipsThenShape) {
  const FitSchedule s = default_fit_schedule();
  ASSERT_EQ(s.per_start.size(), 5u);
  EXPECT_TRUE(s.per_start[0].torso_only);
  EXPECT_FALSE(s.per_start[0].free_pose);
  EXPECT_EQ(s.per_start[1].prior_scale, 10.0);
  EXPECT_EQ(s.per_start[2].prior_scale, 3.0);
  EXPECT_EQ(s.per_start[3].prior_scale, 1.0);
  EXPECT_EQ(s.per_start[4].kind, FitStage::Kind::kDepthFlips);
  ASSERT_EQ(s.refine.size(), 1u);
  EXPECT_TRUE(s.refine[0].free_betas && s.refine[0].silhouette);
  EXPECT_EQ(s.refine[0].rounds, 3);
}

TEST(BodyJoints, FirstChildIsTheLowestNumberedChild) {
  const auto& p = smpl_parents();
  EXPECT_EQ(first_child(p, sj::kPelvis), sj::kLeftHip);
  EXPECT_EQ(first_child(p, sj::kSpine3), sj::kNeck);
  EXPECT_EQ(first_child(p, sj::kLeftElbow), sj::kLeftWrist);
  EXPECT_EQ(first_child(p, sj::kRightHand), -1);
}

}  // namespace ks
