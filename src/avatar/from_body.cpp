#include "avatar/from_body.hpp"

#include <cmath>

#include "body/skin_weights.hpp"
#include "mesh/trimesh.hpp"
#include "raster/sh.hpp"

namespace ks {

Avatar avatar_from_body(const BodyModel& model, const Eigen::VectorXd& betas,
                        const PlainAvatarOptions& opt) {
  BodyParams shape;
  shape.betas = betas;
  shape.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
  const BodyState rest = body_forward(model, shape);
  TriMesh mesh{rest.rest_vertices, model.faces};
  Eigen::SparseMatrix<double, Eigen::RowMajor> S(mesh.V.rows(), mesh.V.rows());
  S.setIdentity();
  if (opt.subdivide > 0) {
    Subdivision sub = subdivide(mesh, opt.subdivide, true);
    mesh = std::move(sub.mesh);
    S = std::move(sub.S);
  }
  const int N = int(mesh.V.rows());
  Avatar a;
  a.body_kind = model.kind_name();
  a.body_model = a.body_kind;
  a.betas = betas;
  a.parents = model.parents;
  a.joint_names = model.joint_names;
  if (int(a.joint_names.size()) != model.num_joints())
    for (int j = int(a.joint_names.size()); j < model.num_joints(); ++j)
      a.joint_names.push_back("joint_" + std::to_string(j));
  a.rest_joints = rest.rest_joints;
  a.template_vertices = mesh.V;
  a.template_faces = mesh.F;

  double edge = 0;
  const auto edges = mesh_edges(mesh.F);
  for (const auto& [i, j] : edges) edge += (mesh.V.row(i) - mesh.V.row(j)).norm();
  edge /= std::max<size_t>(edges.size(), 1);
  const float log_s = float(std::log(std::max(1e-6, opt.scale_factor * edge)));
  const float logit = std::log(opt.opacity / (1.f - opt.opacity));
  constexpr float kC0 = float(sh::kC0);  // SH band-0 basis, in the colours' precision
  a.gaussians.sh_degree = 0;
  a.gaussians.resize(N);
  a.anchors.resize(3 * size_t(N));
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < 3; ++k) {
      a.anchors[3 * i + k] = float(mesh.V(i, k));
      a.gaussians.means[3 * i + k] = float(mesh.V(i, k));
      a.gaussians.log_scales[3 * i + k] = log_s;
      a.gaussians.sh[3 * i + k] = (opt.color[k] - 0.5f) / kC0;
    }
    a.gaussians.opacity_logits[i] = logit;
  }
  const Eigen::MatrixXd W = S * model.weights;
  top_k_skin_weights(W, kAvatarSkinK, a.skin_joints, a.skin_weights);
  if (!model.part_labels.empty()) {
    const auto labels = carry_labels(S, model.part_labels);
    a.part_labels.assign(labels.begin(), labels.end());
  }
  if (opt.posedirs && model.posedirs.size() > 0 && model.posedirs.cwiseAbs().maxCoeff() > 0) {
    // posedirs rows 3v+k: carry each axis through the stencil.
    const int P = int(model.posedirs.cols());
    const int V0 = int(model.v_template.rows());
    a.posedirs.resize(3 * Eigen::Index(N), P);
    for (int k = 0; k < 3; ++k) {
      Eigen::MatrixXd Pk(V0, P);
      for (int v = 0; v < V0; ++v) Pk.row(v) = model.posedirs.row(3 * v + k);
      const Eigen::MatrixXd Qk = S * Pk;
      for (int v = 0; v < N; ++v) a.posedirs.row(3 * v + k) = Qk.row(v).cast<float>();
    }
  }
  a.metadata = {{"source", "avatar_from_body"}, {"subdivide", opt.subdivide}};
  return a;
}

}  // namespace ks
