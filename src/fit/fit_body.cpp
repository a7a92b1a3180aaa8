#include "fit/fit_body.hpp"

#include <algorithm>
#include <numeric>

#include "body/skin_weights.hpp"
#include "core/error.hpp"

namespace ks::fit {

BodyData make_body_data(const BodyModel& model, int num_betas, int vertex_stride,
                        KeypointConvention convention) {
  BodyData d;
  Layout& L = d.layout;
  L.pose_joints = model.num_body_pose_joints();
  L.num_betas = std::clamp(num_betas, 0, model.num_betas);
  L.orient = 0;
  L.pose = 3;
  L.betas = L.pose + 3 * L.pose_joints;
  L.cam = L.betas + L.num_betas;
  L.size = L.cam + 3;
  if (L.size > kMaxParams)
    throw Error("fit: " + std::to_string(L.size) + " parameters, more than the fit handles (" +
                std::to_string(kMaxParams) + ")");
  d.parents = model.parents;
  for (int j = 0; j < int(d.parents.size()); ++j)
    if (d.parents[size_t(j)] >= j) throw Error("fit: the skeleton's parents are not in order");
  const int J = model.num_joints(), V = model.num_vertices();
  d.J0 = model.J_regressor * model.v_template;
  d.Jdirs.setZero(3 * J, L.num_betas);
  for (int b = 0; b < L.num_betas; ++b) {
    Eigen::MatrixXd S(V, 3);
    for (int v = 0; v < V; ++v)
      for (int k = 0; k < 3; ++k) S(v, k) = model.shapedirs(3 * v + k, b);
    const Eigen::MatrixXd JS = model.J_regressor * S;
    for (int j = 0; j < J; ++j)
      for (int k = 0; k < 3; ++k) d.Jdirs(3 * j + k, b) = JS(j, k);
  }
  d.kp = body25_sources(model, convention);
  std::vector<int> ids;
  for (int v = 0; v < V; v += std::max(1, vertex_stride)) ids.push_back(v);
  for (int k = 0; k < kBody25Count; ++k) {
    const int v = d.kp[size_t(k)].vertex;
    if (v < 0) continue;
    auto it = std::find(ids.begin(), ids.end(), v);
    if (it == ids.end()) {
      ids.push_back(v);
      it = ids.end() - 1;
    }
    d.kp_slot[size_t(k)] = int(it - ids.begin());
  }
  d.vertex_ids = ids;
  const int M = int(ids.size());
  d.V0.resize(M, 3);
  d.Vdirs.setZero(3 * M, L.num_betas);
  d.skin_joint.resize(size_t(M));
  d.skin_weight.resize(size_t(M));
  for (int m = 0; m < M; ++m) {
    const int v = ids[size_t(m)];
    d.V0.row(m) = model.v_template.row(v);
    for (int k = 0; k < 3; ++k)
      for (int b = 0; b < L.num_betas; ++b) d.Vdirs(3 * m + k, b) = model.shapedirs(3 * v + k, b);
    top_k_skin_weights(model.weights.row(v), 4, d.skin_joint[size_t(m)].data(),
                       d.skin_weight[size_t(m)].data());
  }
  return d;
}

Eigen::VectorXd pack(const Layout& L, const BodyParams& p, const Eigen::Vector3d& cam_t) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(L.size);
  x.segment<3>(L.orient) = p.global_orient;
  const long n = std::min<long>(3L * L.pose_joints, p.body_pose.size());
  x.segment(L.pose, n) = p.body_pose.head(n);
  const long nb = std::min<long>(L.num_betas, p.betas.size());
  x.segment(L.betas, nb) = p.betas.head(nb);
  x.segment<3>(L.cam) = cam_t;
  return x;
}

BodyParams unpack_params(const Layout& L, const Eigen::VectorXd& x) {
  BodyParams p;
  p.global_orient = x.segment<3>(L.orient);
  p.body_pose = x.segment(L.pose, 3 * L.pose_joints);
  p.betas = x.segment(L.betas, L.num_betas);
  return p;
}

Eigen::Vector3d unpack_cam(const Layout& L, const Eigen::VectorXd& x) {
  return x.segment<3>(L.cam);
}

}  // namespace ks::fit
