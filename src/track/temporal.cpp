#include "track/temporal.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "body/joints.hpp"
#include "body/keypoints.hpp"
#include "core/error.hpp"
#include "core/rotation.hpp"
#include "fit/evaluator.hpp"
#include "fit/fit_body.hpp"
#include "fit/pose_prior.hpp"
#include "fit/silhouette.hpp"
#include "fit/terms.hpp"
#include "track/temporal_terms.hpp"

namespace ks {

namespace {

using fit::BodyData;
using fit::Layout;
using Keypoints = std::array<Eigen::Vector3d, kBody25Count>;

struct Sequence {
  const BodyModel& model;
  const BodyData& d;
  const FitOptions& fo;
  const TemporalOptions& to;
  const std::vector<double>& t;
  std::vector<fit::Projector> pr;
  std::vector<double> unit;
  std::vector<fit::JointPrior> priors;
  int joints = 22;
  std::vector<Camera> cameras;         // per frame (its translation from the parameters)
  std::vector<fit::DistanceField> df;  // per frame the mask's outside distance; empty: none
};

struct Solved {
  double initial = 0, cost = 0, temporal = 0;
  std::vector<std::map<std::string, double>> costs;  // per frame, its own terms
};

// One solve of the whole sequence from xs (changed in place).
Solved solve(const Sequence& s, const std::vector<FitInput>& in, std::vector<Eigen::VectorXd>& xs,
             const std::vector<std::vector<fit::Cover>>& covers) {
  const int n = int(xs.size());
  const Layout& L = s.d.layout;
  const int P = L.size;
  std::vector<std::unique_ptr<fit::Evaluator>> evs;
  std::vector<fit::Evaluator*> raw;
  for (int i = 0; i < n; ++i) {
    const bool sil = !s.df[size_t(i)].d.empty();
    evs.push_back(std::make_unique<fit::Evaluator>(s.d, xs[size_t(i)].data(), sil));
    raw.push_back(evs.back().get());
  }
  track::SequenceEvaluator seq(raw);
  ceres::Problem::Options po;
  po.evaluation_callback = &seq;
  ceres::Problem problem(po);
  FitStage st;
  st.name = "temporal";
  st.free_pose = true;
  st.prior_scale = 1.0;
  std::vector<fit::TermBlocks> groups(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const fit::FrameTerms f{s.d,      in[size_t(i)],    *raw[size_t(i)], s.pr[size_t(i)],
                            s.priors, s.unit[size_t(i)]};
    fit::add_frame_terms(problem, f, s.fo, st, xs[size_t(i)].data(), groups[size_t(i)]);
    if (!s.df[size_t(i)].d.empty())
      fit::add_silhouette_terms(problem, f, s.df[size_t(i)], covers[size_t(i)], s.fo,
                                xs[size_t(i)].data(), groups[size_t(i)]);
  }
  std::vector<ceres::ResidualBlockId> temporal;
  const auto& t = s.t;
  const int Q = track::temporal_point_count(s.joints);
  auto loss = [&]() -> ceres::LossFunction* {
    return s.to.temporal_robust > 0 ? new ceres::CauchyLoss(s.to.temporal_robust) : nullptr;
  };
  if (s.to.sigma_accel > 0)
    for (int i = 1; i + 1 < n; ++i)
      for (int q = 0; q < Q; ++q)
        temporal.push_back(problem.AddResidualBlock(
            track::acceleration_residual(raw[size_t(i - 1)], raw[size_t(i)], raw[size_t(i + 1)],
                                         t[size_t(i - 1)], t[size_t(i)], t[size_t(i + 1)],
                                         s.to.sigma_accel, P, L.cam, s.joints, q),
            loss(), xs[size_t(i - 1)].data(), xs[size_t(i)].data(), xs[size_t(i + 1)].data()));
  if (s.to.sigma_velocity > 0)
    for (int i = 1; i < n; ++i)
      for (int q = 0; q < Q; ++q)
        temporal.push_back(problem.AddResidualBlock(
            track::velocity_residual(raw[size_t(i - 1)], raw[size_t(i)], t[size_t(i - 1)],
                                     t[size_t(i)], s.to.sigma_velocity, P, L.cam, s.joints, q),
            loss(), xs[size_t(i - 1)].data(), xs[size_t(i)].data()));
  if (L.num_betas > 0) {
    std::vector<int> fixed;
    for (int b = 0; b < L.num_betas; ++b) fixed.push_back(L.betas + b);
    for (int i = 0; i < n; ++i)
      problem.SetManifold(xs[size_t(i)].data(), new ceres::SubsetManifold(P, fixed));
  }
  ceres::Solver::Options so;
  // The frames' blocks are coupled only to their neighbours': a sparse solve where Ceres has one.
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE))
    so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE))
    so.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  else
    so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = s.to.max_iterations;
  so.num_threads = 2;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary sum;
  ceres::Solve(so, &problem, &sum);
  Solved out;
  out.initial = sum.initial_cost;
  out.cost = sum.final_cost;
  auto cost_of = [&](const std::vector<ceres::ResidualBlockId>& ids) {
    ceres::Problem::EvaluateOptions eo;
    eo.residual_blocks = ids;
    double c = 0;
    problem.Evaluate(eo, &c, nullptr, nullptr, nullptr);
    return c;
  };
  out.temporal = temporal.empty() ? 0.0 : cost_of(temporal);
  out.costs.resize(size_t(n));
  for (int i = 0; i < n; ++i) {
    double total = 0;
    for (const auto& [name, ids] : groups[size_t(i)]) {
      const double c = cost_of(ids);
      out.costs[size_t(i)][name] = c;
      total += c;
    }
    out.costs[size_t(i)]["total"] = total;
  }
  if (s.to.progress)
    std::fprintf(stderr,
                 "track: temporal solve: cost %.4g -> %.4g (temporal %.4g), %d iterations\n",
                 sum.initial_cost, sum.final_cost, out.temporal, int(sum.iterations.size()));
  return out;
}

// `rounds` solves from xs, the silhouette's cover correspondences renewed before each (the
// single-photo fit's schedule); the first solve's initial cost, the last one's result.
Solved solve_rounds(const Sequence& s, const std::vector<FitInput>& in,
                    std::vector<Eigen::VectorXd>& xs) {
  const int n = int(xs.size());
  const bool sil =
      std::any_of(s.df.begin(), s.df.end(), [](const auto& d) { return !d.d.empty(); });
  const int rounds = sil ? std::max(1, s.to.silhouette_rounds) : 1;
  Solved out;
  for (int r = 0; r < rounds; ++r) {
    std::vector<std::vector<fit::Cover>> covers(static_cast<size_t>(n));
#pragma omp parallel for schedule(dynamic)
    for (int i = 0; i < n; ++i) {
      if (s.df[size_t(i)].d.empty()) continue;
      Camera cam = s.cameras[size_t(i)];
      cam.t = fit::unpack_cam(s.d.layout, xs[size_t(i)]);
      covers[size_t(i)] = fit::cover_correspondences(
          s.model, s.d, fit::unpack_params(s.d.layout, xs[size_t(i)]), cam, in[size_t(i)].mask);
    }
    const double initial = out.initial;
    out = solve(s, in, xs, covers);
    if (r > 0) out.initial = initial;
  }
  return out;
}

// The frame's joints and BODY_25 points in its camera's frame (as the temporal terms follow them).
std::vector<Eigen::Vector3d> camera_points(const BodyData& d, const Eigen::VectorXd& x,
                                           int joints) {
  std::vector<Eigen::Vector3d> J, V, K;
  fit::forward<double>(d, x.data(), J, &V, nullptr, &K);
  const Eigen::Vector3d t = x.segment<3>(d.layout.cam);
  std::vector<Eigen::Vector3d> out;
  for (int j = 0; j < joints; ++j) out.push_back(fit::to_camera(J[size_t(j)], t));
  for (const auto& k : K) out.push_back(fit::to_camera(k, t));
  return out;
}

// Keypoints with the left and right of `group`'s pairs exchanged.
Keypoints exchanged(const Keypoints& k, const std::vector<int>& group) {
  Keypoints out = k;
  for (int a : group) out[size_t(body25_mirror(a))] = k[size_t(a)];
  return out;
}

const std::vector<std::vector<int>>& swap_groups() {
  using namespace body25;
  static const std::vector<int> legs = {kRHip,      kLHip,      kRKnee,   kLKnee,
                                        kRAnkle,    kLAnkle,    kRBigToe, kLBigToe,
                                        kRSmallToe, kLSmallToe, kRHeel,   kLHeel};
  static const std::vector<int> arms = {kRShoulder, kLShoulder, kRElbow, kLElbow, kRWrist, kLWrist};
  static const std::vector<std::vector<int>> groups = [] {
    std::vector<int> all = legs;
    all.insert(all.end(), arms.begin(), arms.end());
    for (int k : {kREye, kLEye, kREar, kLEar}) all.push_back(k);
    return std::vector<std::vector<int>>{legs, arms, all};
  }();
  return groups;
}

// The keypoints' robust cost against predicted pixel positions (the fit's keypoint term).
double label_cost(const Keypoints& k, const std::vector<Eigen::Vector2d>& pred, double unit,
                  const FitOptions& o) {
  const double s2 = o.keypoint_robust * o.keypoint_robust;
  double c = 0;
  for (int q = 0; q < kBody25Count; ++q) {
    if (!(k[size_t(q)].z() > 0)) continue;
    const double r2 = (k[size_t(q)].head<2>() - pred[size_t(q)]).squaredNorm() / (unit * unit);
    c += fit::keypoint_group_weight(q, o) * k[size_t(q)].z() * s2 * std::log1p(r2 / s2);
  }
  return c;
}

Eigen::VectorXd interpolate(const Layout& L, const Eigen::VectorXd& a, const Eigen::VectorXd& b,
                            double w) {
  Eigen::VectorXd x = a;
  x.segment<3>(L.orient) =
      interpolate_axis_angle(a.segment<3>(L.orient), b.segment<3>(L.orient), w);
  for (int j = 0; j < L.pose_joints; ++j)
    x.segment<3>(L.pose + 3 * j) =
        interpolate_axis_angle(a.segment<3>(L.pose + 3 * j), b.segment<3>(L.pose + 3 * j), w);
  x.segment<3>(L.cam) = (1 - w) * a.segment<3>(L.cam) + w * b.segment<3>(L.cam);
  return x;
}

}  // namespace

TemporalReport solve_temporal(const BodyModel& model, std::vector<FitInput>& inputs,
                              const std::vector<double>& times, const Eigen::VectorXd& betas,
                              std::vector<FitResult>& fits, const FitOptions& fo,
                              const TemporalOptions& to) {
  TemporalReport rep;
  const int n = int(fits.size());
  if (!to.enabled || n < 3) return rep;
  if (int(inputs.size()) != n || int(times.size()) != n)
    throw Error("track: the temporal solve needs one input and one time per frame");
  for (int i = 1; i < n; ++i)
    if (!(times[size_t(i)] > times[size_t(i - 1)]))
      throw Error("track: the temporal solve needs frames in increasing time");
  const auto t0 = std::chrono::steady_clock::now();
  const BodyData d = fit::make_body_data(model, fo.num_betas, fo.vertex_stride, fo.keypoints);
  const Layout& L = d.layout;
  Sequence s{model,
             d,
             fo,
             to,
             times,
             {},
             {},
             fit::make_joint_priors(d, fo.stance_arm_down_degrees, fo.w_limits),
             std::min(to.joints, int(d.parents.size())),
             {},
             {}};
  std::vector<Eigen::VectorXd> xs;
  for (int i = 0; i < n; ++i) {
    const FitResult& f = fits[size_t(i)];
    fit::Projector pr;
    pr.f = f.camera.fx;
    pr.cx = f.camera.cx;
    pr.cy = f.camera.cy;
    pr.cam = L.cam;
    s.pr.push_back(pr);
    s.unit.push_back(fit::person_height_px(inputs[size_t(i)]) / 100.0);
    s.cameras.push_back(f.camera);
    const bool sil = to.silhouette && fo.use_silhouette && !inputs[size_t(i)].mask.empty();
    s.df.push_back(sil ? fit::outside_distance(inputs[size_t(i)].mask) : fit::DistanceField{});
    BodyParams p = f.params;
    p.betas = betas;
    xs.push_back(fit::pack(L, p, f.camera.t));
  }
  Solved best = solve_rounds(s, inputs, xs);
  rep.solves = 1;
  rep.cost_before = best.initial;

  std::vector<int> swapped_at(size_t(n), 0), restarted_at(size_t(n), 0);
  for (int round = 0; round < 2 && (to.fix_swaps || to.reinit_deviations > 0); ++round) {
    std::vector<FitInput> cand_in = inputs;
    std::vector<Eigen::VectorXd> cand_x = xs;
    std::vector<std::vector<Eigen::Vector3d>> pts(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) pts[size_t(i)] = camera_points(d, xs[size_t(i)], s.joints);
    std::vector<double> dev(size_t(n), 0.0), sd(size_t(n), 1e300);
    for (int i = 1; i + 1 < n; ++i) {
      const double h0 = times[size_t(i)] - times[size_t(i - 1)];
      const double h1 = times[size_t(i + 1)] - times[size_t(i)];
      const double w = h0 / (h0 + h1);
      double ss = 0;
      std::vector<Eigen::Vector2d> pred(kBody25Count);
      for (size_t q = 0; q < pts[size_t(i)].size(); ++q) {
        const Eigen::Vector3d m = (1 - w) * pts[size_t(i - 1)][q] + w * pts[size_t(i + 1)][q];
        ss += (pts[size_t(i)][q] - m).squaredNorm();
        if (int(q) >= s.joints) {
          const fit::Projector& pr = s.pr[size_t(i)];
          pred[q - size_t(s.joints)] =
              Eigen::Vector2d(pr.f * m.x() / m.z() + pr.cx, pr.f * m.y() / m.z() + pr.cy);
        }
      }
      dev[size_t(i)] = std::sqrt(ss / double(pts[size_t(i)].size()));
      if (to.sigma_accel > 0)
        sd[size_t(i)] =
            std::sqrt(3.0) * h0 * h1 / (h0 + h1) * to.sigma_accel * std::sqrt((h0 + h1) / 3.0);
      if (to.fix_swaps) {
        const Keypoints& k = inputs[size_t(i)].keypoints;
        const double unit = s.unit[size_t(i)];
        const double given = label_cost(k, pred, unit, fo);
        double bestc = given;
        int bestg = -1;
        for (size_t g = 0; g < swap_groups().size(); ++g) {
          const double c = label_cost(exchanged(k, swap_groups()[g]), pred, unit, fo);
          if (c < bestc) {
            bestc = c;
            bestg = int(g);
          }
        }
        if (bestg >= 0 && bestc < to.swap_ratio * given) {
          cand_in[size_t(i)].keypoints = exchanged(k, swap_groups()[size_t(bestg)]);
          cand_x[size_t(i)] = interpolate(L, xs[size_t(i - 1)], xs[size_t(i + 1)], w);
          swapped_at[size_t(i)] = round + 1;
        }
      }
    }
    if (to.reinit_deviations > 0)
      for (int i = 1; i + 1 < n; ++i) {
        const bool peak =
            dev[size_t(i)] >= dev[size_t(i - 1)] && dev[size_t(i)] >= dev[size_t(i + 1)];
        if (peak && dev[size_t(i)] > to.reinit_deviations * sd[size_t(i)] &&
            swapped_at[size_t(i)] != round + 1) {
          const double h0 = times[size_t(i)] - times[size_t(i - 1)];
          const double h1 = times[size_t(i + 1)] - times[size_t(i)];
          cand_x[size_t(i)] = interpolate(L, xs[size_t(i - 1)], xs[size_t(i + 1)], h0 / (h0 + h1));
          restarted_at[size_t(i)] = round + 1;
        }
      }
    const bool any =
        std::any_of(swapped_at.begin(), swapped_at.end(), [&](int v) { return v == round + 1; }) ||
        std::any_of(restarted_at.begin(), restarted_at.end(),
                    [&](int v) { return v == round + 1; });
    if (!any) break;
    Solved c = solve_rounds(s, cand_in, cand_x);
    ++rep.solves;
    if (!(c.cost < best.cost)) {
      for (int& v : swapped_at) v = v == round + 1 ? 0 : v;
      for (int& v : restarted_at) v = v == round + 1 ? 0 : v;
      break;
    }
    best = std::move(c);
    inputs = std::move(cand_in);
    xs = std::move(cand_x);
  }
  for (int i = 0; i < n; ++i) {
    if (swapped_at[size_t(i)]) rep.swapped.push_back(i);
    if (restarted_at[size_t(i)]) rep.restarted.push_back(i);
    FitResult& f = fits[size_t(i)];
    f.params = fit::unpack_params(L, xs[size_t(i)]);
    f.params.betas = betas;
    f.camera.t = fit::unpack_cam(L, xs[size_t(i)]);
    f.costs = best.costs[size_t(i)];
    std::vector<Eigen::Vector3d> J;
    fit::forward<double>(d, xs[size_t(i)].data(), J, nullptr);
    const Eigen::Vector3d fwd =
        axis_angle_to_matrix(Eigen::Vector3d(f.params.global_orient)) * Eigen::Vector3d::UnitZ();
    f.facing_camera = fwd.dot(f.camera.centre() - J[size_t(smpl_joint::kPelvis)]) > 0;
  }
  rep.applied = true;
  rep.cost_after = best.cost;
  rep.temporal_cost = best.temporal;
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace ks
