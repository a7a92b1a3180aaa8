#include "fit/terms.hpp"

#include <algorithm>
#include <cmath>

#include "body/joints.hpp"
#include "fit/residuals.hpp"
#include "meshrender/meshrender.hpp"

namespace ks::fit {

namespace {
constexpr double kDeg = M_PI / 180.0;
namespace sj = smpl_joint;
}  // namespace

double keypoint_group_weight(int k, const FitOptions& o) {
  using namespace body25;
  if (k == kNose || (k >= kREye && k <= kLEar)) return o.w_face;
  if (k >= kLBigToe) return o.w_feet;
  return 1.0;
}

bool is_torso_keypoint(int k) {
  using namespace body25;
  return k == kNeck || k == kLShoulder || k == kRShoulder || k == kMidHip || k == kLHip ||
         k == kRHip;
}

double person_height_px(const FitInput& in) {
  double ymin = 1e18, ymax = -1e18;
  if (!in.mask.empty()) {
    for (int y = 0; y < in.height; ++y)
      for (int x = 0; x < in.width; ++x)
        if (in.mask.at(x, y, 0) >= 0.5f) {
          ymin = std::min(ymin, double(y));
          ymax = std::max(ymax, double(y + 1));
        }
  }
  if (!(ymax > ymin)) {
    for (const auto& k : in.keypoints)
      if (k.z() > 0) {
        ymin = std::min(ymin, k.y());
        ymax = std::max(ymax, k.y());
      }
    ymax = ymin + 1.15 * (ymax - ymin);
  }
  return std::max(10.0, ymax - ymin);
}

void add_frame_terms(ceres::Problem& problem, const FrameTerms& f, const FitOptions& o,
                     const FitStage& s, double* x, TermBlocks& groups) {
  const Layout& L = f.d.layout;
  const int P = L.size;
  for (int k = 0; k < kBody25Count; ++k) {
    const Eigen::Vector3d& kp = f.in.keypoints[size_t(k)];
    if (!(kp.z() > 0) || (s.torso_only && !is_torso_keypoint(k))) continue;
    const double w = o.w_keypoints * keypoint_group_weight(k, o) * kp.z();
    auto* loss =
        new ceres::ScaledLoss(new ceres::CauchyLoss(o.keypoint_robust), w, ceres::TAKE_OWNERSHIP);
    groups["keypoints"].push_back(problem.AddResidualBlock(
        new KeypointResidual(f.ev, f.pr, k, kp.head<2>(), f.unit, P), loss, x));
  }
  if (s.free_pose) {
    for (int j = 1; j <= L.pose_joints; ++j) {
      JointPrior jp = f.priors[size_t(j - 1)];
      jp.w_stance = s.prior_scale * o.w_pose_prior;
      groups["pose_prior"].push_back(
          problem.AddResidualBlock(new PoseResidual(jp, L.pose + 3 * (j - 1), P), nullptr, x));
      groups["joint_limits"].push_back(
          problem.AddResidualBlock(new LimitResidual(jp, L.pose + 3 * (j - 1), P), nullptr, x));
    }
    for (int j : {sj::kLeftElbow, sj::kRightElbow, sj::kLeftWrist, sj::kRightWrist})
      groups["arms_torso"].push_back(problem.AddResidualBlock(
          new ArmTorsoResidual(f.ev, j, 0.10, o.w_arm_torso, P), nullptr, x));
  }
  if (o.w_upright > 0 && !s.torso_only)
    groups["upright"].push_back(problem.AddResidualBlock(
        new UprightResidual(L.orient, o.upright_sigma_degrees * kDeg, o.w_upright, P), nullptr, x));
  if (o.w_ground > 0 && s.free_pose)
    groups["ground"].push_back(
        problem.AddResidualBlock(new GroundResidual(f.ev, sj::kLeftAnkle, sj::kRightAnkle, P),
                                 new ceres::ScaledLoss(new ceres::CauchyLoss(o.ground_robust_cm),
                                                       o.w_ground, ceres::TAKE_OWNERSHIP),
                                 x));
  if (s.free_betas && L.num_betas > 0)
    groups["shape_prior"].push_back(problem.AddResidualBlock(
        new ShapeResidual(L.betas, L.num_betas, o.w_shape, P), nullptr, x));
}

std::vector<Cover> cover_correspondences(const BodyModel& model, const BodyData& d,
                                         const BodyParams& p, const Camera& cam,
                                         const Image& mask) {
  const BodyState st = body_forward(model, p);
  MeshRenderOptions ro;
  ro.want_rgb = false;
  ro.want_depth = true;
  MeshRenderInput ri;
  ri.vertices = &st.vertices;
  ri.faces = &model.faces;
  const MeshRenderOutput r = render_mesh(cam, ri, ro);
  // Vertices of the subset on the body's outline.
  const auto rv = rim_vertices(st.vertices, &d.vertex_ids, cam, r, 0.03);
  std::vector<int> rim;
  std::vector<Eigen::Vector2d> rim_uv;
  for (const auto& v : rv) {
    rim.push_back(v.slot);
    rim_uv.push_back(v.uv);
  }
  std::vector<Cover> out;
  if (rim.empty()) return out;
  const auto samples = outline_samples(mask, 3.0, 600);
  for (const auto& q : samples) {
    int bi = -1;
    double bd = 1e300;
    for (size_t i = 0; i < rim.size(); ++i) {
      const double dd = (rim_uv[i] - q).squaredNorm();
      if (dd < bd) {
        bd = dd;
        bi = int(i);
      }
    }
    out.push_back({rim[size_t(bi)], q});
  }
  return out;
}

void add_silhouette_terms(ceres::Problem& problem, const FrameTerms& f, const DistanceField& df,
                          const std::vector<Cover>& covers, const FitOptions& o, double* x,
                          TermBlocks& groups) {
  const Layout& L = f.d.layout;
  const int P = L.size;
  const int M = int(f.d.vertex_ids.size());
  const double w_in = o.w_sil_inside * 100.0 / M;
  for (int m = 0; m < M; ++m)
    groups["silhouette_inside"].push_back(
        problem.AddResidualBlock(new InsideResidual(f.ev, f.pr, df, m, f.unit, P),
                                 new ceres::ScaledLoss(nullptr, w_in, ceres::TAKE_OWNERSHIP), x));
  if (covers.empty()) return;
  const double depth = x[L.cam + 2];
  const double allowance = f.pr.f * o.clothing_allowance / std::max(0.1, depth);
  const double w_c = o.w_sil_cover * 100.0 / double(covers.size());
  for (const Cover& c : covers)
    groups["silhouette_cover"].push_back(problem.AddResidualBlock(
        new CoverResidual(f.ev, f.pr, c.vertex, c.q, allowance, f.unit, P),
        new ceres::ScaledLoss(new ceres::CauchyLoss(o.cover_robust), w_c, ceres::TAKE_OWNERSHIP),
        x));
}

}  // namespace ks::fit
