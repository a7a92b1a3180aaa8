#include "fit/fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "body/joints.hpp"
#include "core/env.hpp"
#include "core/error.hpp"
#include "fit/evaluator.hpp"
#include "fit/fit_body.hpp"
#include "fit/pose_prior.hpp"
#include "fit/residuals.hpp"
#include "fit/silhouette.hpp"
#include "fit/terms.hpp"
#include "meshrender/meshrender.hpp"

namespace ks {

namespace {
constexpr double kDeg = M_PI / 180.0;
}  // namespace

FitSchedule default_fit_schedule() {
  FitSchedule s;
  FitStage torso;
  torso.name = "torso";
  torso.torso_only = true;
  s.per_start.push_back(torso);
  for (double scale : {10.0, 3.0, 1.0}) {
    FitStage pose;
    pose.name = "pose";
    pose.free_pose = true;
    pose.prior_scale = scale;
    s.per_start.push_back(pose);
  }
  FitStage flips;
  flips.name = "depth flips";
  flips.kind = FitStage::Kind::kDepthFlips;
  flips.free_pose = true;
  flips.prior_scale = 1.0;
  s.per_start.push_back(flips);
  FitStage shape;
  shape.name = "pose+shape+silhouette";
  shape.free_pose = true;
  shape.free_betas = true;
  shape.prior_scale = 1.0;
  shape.silhouette = true;
  shape.rounds = 3;
  s.refine.push_back(shape);
  return s;
}

double fit_focal(const FitOptions& o, int width, int height) {
  return o.focal > 0 ? o.focal
                     : 0.5 * std::max(width, height) / std::tan(0.5 * o.fov_degrees * kDeg);
}

double fit_focal(const FitOptions& o, const FitInput& in, std::string* source) {
  const char* from = o.focal > 0 ? "option" : in.metadata_focal > 0 ? "metadata" : "field of view";
  if (source) *source = from;
  if (o.focal <= 0 && in.metadata_focal > 0) return in.metadata_focal;
  return fit_focal(o, in.width, in.height);
}

Camera fit_camera(const FitOptions& o, int width, int height, const Eigen::Vector3d& t) {
  Camera c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = fit_focal(o, width, height);
  c.cx = 0.5 * width;
  c.cy = 0.5 * height;
  c.R = fit::camera_rotation();
  c.t = t;
  return c;
}

namespace {

using fit::BodyData;
using fit::Layout;
namespace sj = smpl_joint;

// The limbs (and pairs) a depth-flips stage mirrors, by the joint at the top of each.
const std::vector<std::vector<int>> kDepthFlipLimbs = {
    {sj::kLeftShoulder}, {sj::kRightShoulder},          {sj::kLeftHip},
    {sj::kRightHip},     {sj::kLeftHip, sj::kRightHip}, {sj::kLeftShoulder, sj::kRightShoulder}};

using fit::TermBlocks;

class Fitter {
 public:
  Fitter(const BodyModel& model, const FitInput& in, const FitOptions& o)
      : model_(model),
        in_(in),
        o_(o),
        d_(fit::make_body_data(model, o.num_betas, o.vertex_stride, o.keypoints)) {
    pr_.f = fit_focal(o, in.width, in.height);
    pr_.cx = 0.5 * in.width;
    pr_.cy = 0.5 * in.height;
    pr_.cam = d_.layout.cam;
    priors_ = fit::make_joint_priors(d_, o.stance_arm_down_degrees, o.w_limits);
    has_mask_ = !in.mask.empty() && o.use_silhouette;
    if (has_mask_) df_ = fit::outside_distance(in.mask);
    unit_ = fit::person_height_px(in) / 100.0;
  }

  FitResult run() {
    const auto t0 = std::chrono::steady_clock::now();
    const Layout& L = d_.layout;
    FitResult best;
    double best_cost = 1e300;
    Eigen::VectorXd best_x;
    for (int facing = 0; facing < 2; ++facing) {
      Eigen::VectorXd x = initial(facing == 0);
      const double c = run_stages(x, o_.schedule.per_start, 0.0, nullptr);
      if (c < best_cost) {
        best_cost = c;
        best_x = x;
      }
    }
    Eigen::VectorXd x = best_x;
    run_stages(x, o_.schedule.refine, best_cost, &best.costs);
    best.params = fit::unpack_params(L, x);
    const Camera cam = fit_camera(o_, in_.width, in_.height, fit::unpack_cam(L, x));
    {  // Facing the camera: the pelvis' forward axis (+Z at rest) points towards it.
      std::vector<Eigen::Vector3d> J;
      fit::forward<double>(d_, x.data(), J, nullptr);
      const Eigen::Vector3d fwd =
          axis_angle_to_matrix<double>(Eigen::Vector3d(best.params.global_orient)) *
          Eigen::Vector3d::UnitZ();
      best.facing_camera = fwd.dot(cam.centre() - J[sj::kPelvis]) > 0;
    }
    best.params.betas.conservativeResize(L.num_betas);
    best.camera = cam;
    best.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return best;
  }

 private:
  bool has(int k) const { return in_.keypoints[size_t(k)].z() > 0; }
  Eigen::Vector2d kp(int k) const { return in_.keypoints[size_t(k)].head<2>(); }
  bool silhouette(const FitStage& s) const { return s.silhouette && has_mask_; }

  // Runs `stages` in order on x; `cost` is the cost before them (what a depth-flips stage must
  // beat). Returns the last stage's final cost; `costs`: the last solve's per-term costs.
  double run_stages(Eigen::VectorXd& x, const std::vector<FitStage>& stages, double cost,
                    std::map<std::string, double>* costs) {
    for (size_t i = 0; i < stages.size(); ++i) {
      const FitStage& s = stages[i];
      const bool last = i + 1 == stages.size();
      if (s.kind == FitStage::Kind::kDepthFlips) {
        cost = depth_flips(x, cost, s);
        continue;
      }
      const int rounds = silhouette(s) ? std::max(1, s.rounds) : 1;
      for (int r = 0; r < rounds; ++r) {
        if (silhouette(s)) covers_ = correspondences(x);
        cost = solve(x, s, last && r + 1 == rounds ? costs : nullptr);
      }
    }
    return cost;
  }

  // A standing start: the natural stance (zero pose), facing the camera or turned away, placed
  // so that the torso's length and position match the keypoints'.
  Eigen::VectorXd initial(bool facing) const {
    using namespace body25;
    const Layout& L = d_.layout;
    BodyParams p;
    p.global_orient = Eigen::Vector3d(0, facing ? 0.0 : M_PI, 0);
    p.body_pose = Eigen::VectorXd::Zero(3 * L.pose_joints);
    p.betas = Eigen::VectorXd::Zero(L.num_betas);
    const int given = std::min(L.num_betas, int(o_.initial_betas.size()));
    if (given > 0) p.betas.head(given) = o_.initial_betas.head(given);
    auto mid = [&](int a, int b, Eigen::Vector2d* out) {
      if (!has(a) || !has(b)) return false;
      *out = 0.5 * (kp(a) + kp(b));
      return true;
    };
    Eigen::Vector2d top, bottom;
    bool ok_top = has(kNeck) ? (top = kp(kNeck), true) : mid(kLShoulder, kRShoulder, &top);
    bool ok_bottom = has(kMidHip) ? (bottom = kp(kMidHip), true) : mid(kLHip, kRHip, &bottom);
    if (!ok_top || !ok_bottom)
      throw Error(
          "fit: the torso is not visible (needs the neck or both shoulders, and the "
          "mid-hip or both hips)");
    const Eigen::Vector3d jn = d_.J0.row(sj::kNeck).transpose();
    const Eigen::Vector3d jh =
        0.5 * (d_.J0.row(sj::kLeftHip) + d_.J0.row(sj::kRightHip)).transpose();
    const double len3 = (jn - jh).norm();
    const double len2 = std::max(1.0, (top - bottom).norm());
    const double z = pr_.f * len3 / len2;
    Eigen::Vector3d P = jh;  // mid-hip, rotated with the body about the root joint
    if (!facing) {
      const Eigen::Vector3d r = d_.J0.row(sj::kPelvis).transpose();
      P = r + Eigen::Vector3d(-(P.x() - r.x()), P.y() - r.y(), -(P.z() - r.z()));
    }
    Eigen::Vector3d t;
    t.x() = (bottom.x() - pr_.cx) * z / pr_.f - P.x();
    t.y() = (bottom.y() - pr_.cy) * z / pr_.f + P.y();
    t.z() = z + P.z();
    return fit::pack(L, p, t);
  }

  // Depth ambiguity: a limb seen from the camera looks the same bent towards it or away from it.
  // Tries each limb (and each pair) mirrored in depth, solved with stage s's terms, keeps what
  // lowers the cost; returns it.
  double depth_flips(Eigen::VectorXd& x, double cost, const FitStage& s) {
    for (const auto& limbs : kDepthFlipLimbs) {
      Eigen::VectorXd y = x;
      for (int j : limbs) flip_limb(y, j);
      const double c = solve(y, s);
      if (c < cost) {
        cost = c;
        x = y;
      }
    }
    return cost;
  }

  // Rotates joint j's bone (and everything below it) so that the bone's direction is mirrored
  // through the plane across the camera ray at the joint: the same picture, the other depth.
  void flip_limb(Eigen::VectorXd& x, int j) const {
    const Layout& L = d_.layout;
    if (j < 1 || j > L.pose_joints) return;
    const int child = first_child(d_.parents, j);
    if (child < 0) return;
    std::vector<Eigen::Vector3d> J;
    fit::forward<double>(d_, x.data(), J, nullptr);
    // World rotations of j's parent and of j.
    std::vector<Eigen::Matrix3d> Rw(d_.parents.size());
    for (size_t k = 0; k < d_.parents.size(); ++k) {
      const int p = d_.parents[k];
      Eigen::Vector3d aa = Eigen::Vector3d::Zero();
      if (k == 0)
        aa = x.segment<3>(L.orient);
      else if (int(k) <= L.pose_joints)
        aa = x.segment<3>(L.pose + 3 * (int(k) - 1));
      const Eigen::Matrix3d R = axis_angle_to_matrix<double>(aa);
      Rw[k] = p < 0 ? R : Eigen::Matrix3d(Rw[size_t(p)] * R);
    }
    const Camera cam = fit_camera(o_, in_.width, in_.height, fit::unpack_cam(L, x));
    const Eigen::Vector3d ray = (J[size_t(j)] - cam.centre()).normalized();
    const Eigen::Vector3d d = J[size_t(child)] - J[size_t(j)];
    const Eigen::Vector3d d2 = d - 2.0 * d.dot(ray) * ray;
    const Eigen::Matrix3d Q = Eigen::Quaterniond::FromTwoVectors(d, d2).toRotationMatrix();
    const Eigen::Matrix3d Rp = Rw[size_t(d_.parents[size_t(j)])];
    const Eigen::AngleAxisd aa(Eigen::Matrix3d(Rp.transpose() * Q * Rw[size_t(j)]));
    x.segment<3>(L.pose + 3 * (j - 1)) = aa.angle() * aa.axis();
  }

  std::vector<fit::Cover> correspondences(const Eigen::VectorXd& x) const {
    const Layout& L = d_.layout;
    return fit::cover_correspondences(model_, d_, fit::unpack_params(L, x),
                                      fit_camera(o_, in_.width, in_.height, fit::unpack_cam(L, x)),
                                      in_.mask);
  }

  // Stage s's terms at x into `problem`, each term's blocks under its name in `groups`.
  void add_terms(ceres::Problem& problem, const fit::Evaluator& ev, Eigen::VectorXd& x,
                 const FitStage& s, TermBlocks& groups) const {
    const fit::FrameTerms f{d_, in_, ev, pr_, priors_, unit_};
    fit::add_frame_terms(problem, f, o_, s, x.data(), groups);
    if (silhouette(s)) fit::add_silhouette_terms(problem, f, df_, covers_, o_, x.data(), groups);
  }

  // One Levenberg-Marquardt solve of stage s; returns the final cost. `costs`: per-term costs.
  double solve(Eigen::VectorXd& x, const FitStage& s,
               std::map<std::string, double>* costs = nullptr) {
    const Layout& L = d_.layout;
    const int P = L.size;
    fit::Evaluator ev(d_, x.data(), silhouette(s));
    ceres::Problem::Options po;
    po.evaluation_callback = &ev;
    ceres::Problem problem(po);
    TermBlocks groups;
    add_terms(problem, ev, x, s, groups);
    std::vector<int> fixed;
    auto fix = [&](int off, int n) {
      for (int i = 0; i < n; ++i) fixed.push_back(off + i);
    };
    if (!s.free_orient) fix(L.orient, 3);
    if (!s.free_pose) fix(L.pose, 3 * L.pose_joints);
    if (!s.free_betas) fix(L.betas, L.num_betas);
    if (!s.free_cam) fix(L.cam, 3);
    if (int(fixed.size()) == P) return 0;
    if (!fixed.empty()) problem.SetManifold(x.data(), new ceres::SubsetManifold(P, fixed));

    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = o_.max_iterations;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    ceres::Solver::Summary sum;
    ceres::Solve(so, &problem, &sum);
    if (o_.progress)
      std::fprintf(stderr, "fit: stage %s: cost %.4g -> %.4g, %d iterations\n", s.name.c_str(),
                   sum.initial_cost, sum.final_cost, int(sum.iterations.size()));
    const bool debug = env_flag("KS_FIT_DEBUG");
    if (costs || debug) {
      std::map<std::string, double> tmp;
      if (!costs) costs = &tmp;
      for (const auto& [name, ids] : groups) {
        ceres::Problem::EvaluateOptions eo;
        eo.residual_blocks = ids;
        eo.apply_loss_function = true;
        double c = 0;
        problem.Evaluate(eo, &c, nullptr, nullptr, nullptr);
        (*costs)[name] = c;
      }
      (*costs)["total"] = sum.final_cost;
      if (debug)
        for (const auto& [k, v] : *costs) std::fprintf(stderr, "   %s %.3f\n", k.c_str(), v);
    }
    return sum.final_cost;
  }

  const BodyModel& model_;
  const FitInput& in_;
  const FitOptions& o_;
  BodyData d_;
  fit::Projector pr_;
  std::vector<fit::JointPrior> priors_;
  bool has_mask_ = false;
  fit::DistanceField df_;
  double unit_ = 1;
  std::vector<fit::Cover> covers_;
};

}  // namespace

FitResult fit_body(const BodyModel& model, const FitInput& input, const FitOptions& options) {
  if (input.width <= 0 || input.height <= 0) throw Error("fit: the image size is not positive");
  if (!input.mask.empty() && (input.mask.width != input.width || input.mask.height != input.height))
    throw Error("fit: the mask is " + std::to_string(input.mask.width) + "x" +
                std::to_string(input.mask.height) + ", the image " + std::to_string(input.width) +
                "x" + std::to_string(input.height));
  if (options.schedule.per_start.empty() && options.schedule.refine.empty())
    throw Error("fit: the stage schedule is empty");
  FitOptions o = options;
  o.focal = fit_focal(options, input);
  Fitter f(model, input, o);
  return f.run();
}

}  // namespace ks
