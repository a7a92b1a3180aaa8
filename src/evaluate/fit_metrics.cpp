#include "evaluate/fit_metrics.hpp"

#include <algorithm>
#include <cmath>

#include "evaluate/pose_metrics.hpp"
#include "meshrender/meshrender.hpp"

namespace ks {

namespace {

Eigen::MatrixXd camera_joints(const BodyState& st, const Camera& cam, int n) {
  Eigen::MatrixXd J(n, 3);
  for (int j = 0; j < n; ++j) J.row(j) = cam.to_camera(st.joints.row(j).transpose()).transpose();
  return J;
}

Image body_mask(const BodyModel& model, const BodyState& st, const Camera& cam) {
  MeshRenderInput ri;
  ri.vertices = &st.vertices;
  ri.faces = &model.faces;
  MeshRenderOptions ro;
  ro.want_rgb = false;
  ro.supersample = 2;
  return render_mesh(cam, ri, ro).mask;
}

bool smpl_skeleton(BodyKind k) {
  return k == BodyKind::kSMPL || k == BodyKind::kDefault;
}

}  // namespace

nlohmann::json FitMetrics::to_json() const {
  return {{"joints", joints},
          {"mpjpe_mm", mpjpe_mm},
          {"pa_mpjpe_mm", pa_mpjpe_mm},
          {"silhouette_iou", silhouette_iou},
          {"rest_vertex_error_mm", std::isnan(rest_vertex_error_mm)
                                       ? nlohmann::json(nullptr)
                                       : nlohmann::json(rest_vertex_error_mm)},
          {"pa_per_joint_mm", pa_per_joint_mm},
          {"estimate_joints_mm", estimate_joints_mm},
          {"truth_joints_mm", truth_joints_mm}};
}

FitMetrics evaluate_fit(const SubjectFit& est, const SubjectFit& truth) {
  FitMetrics m;
  const BodyState se = body_forward(*est.model, est.params);
  const BodyState st = body_forward(*truth.model, truth.params);
  m.joints = smpl_skeleton(est.model->kind) && smpl_skeleton(truth.model->kind) ? 24 : 22;
  const Eigen::MatrixXd Je = camera_joints(se, est.camera, m.joints);
  const Eigen::MatrixXd Jt = camera_joints(st, truth.camera, m.joints);
  m.mpjpe_mm = 1000.0 * mpjpe(Je, Jt, 0);
  Eigen::VectorXd per;
  m.pa_mpjpe_mm = 1000.0 * pa_mpjpe(Je, Jt, &per);
  for (long i = 0; i < per.size(); ++i) m.pa_per_joint_mm.push_back(1000.0 * per(i));
  for (int j = 0; j < m.joints; ++j) {
    const Eigen::Vector3d e = 1000.0 * (Je.row(j) - Je.row(0)).transpose();
    const Eigen::Vector3d t = 1000.0 * (Jt.row(j) - Jt.row(0)).transpose();
    m.estimate_joints_mm.push_back({e.x(), e.y(), e.z()});
    m.truth_joints_mm.push_back({t.x(), t.y(), t.z()});
  }
  Camera ce = est.camera;
  if (ce.width != truth.camera.width || ce.height != truth.camera.height) {
    const double sx = double(truth.camera.width) / ce.width;
    const double sy = double(truth.camera.height) / ce.height;
    ce.fx *= sx;
    ce.cx *= sx;
    ce.fy *= sy;
    ce.cy *= sy;
    ce.width = truth.camera.width;
    ce.height = truth.camera.height;
  }
  m.silhouette_iou =
      mask_iou(body_mask(*est.model, se, ce), body_mask(*truth.model, st, truth.camera));
  m.rest_vertex_error_mm = NAN;
  if (est.model->faces.rows() == truth.model->faces.rows() &&
      est.model->v_template.rows() == truth.model->v_template.rows()) {
    BodyParams re, rt;
    re.betas = est.params.betas;
    rt.betas = truth.params.betas;
    const BodyState be = body_forward(*est.model, re), bt = body_forward(*truth.model, rt);
    const Eigen::RowVector3d d = be.joints.row(0) - bt.joints.row(0);
    double sum = 0;
    for (long v = 0; v < be.vertices.rows(); ++v)
      sum += (be.vertices.row(v) - d - bt.vertices.row(v)).norm();
    m.rest_vertex_error_mm = 1000.0 * sum / double(std::max<long>(1, be.vertices.rows()));
  }
  return m;
}

namespace {

// Green = truth, red = estimate, yellow = both; white background.
Image compose(const Image& me, const Image& mt) {
  Image out(me.width, me.height, 3, 1.f);
  for (int y = 0; y < me.height; ++y)
    for (int x = 0; x < me.width; ++x) {
      const float a = me.at(x, y, 0), b = mt.at(x, y, 0);
      if (a == 0 && b == 0) continue;
      out.at(x, y, 0) = 0.9f * a + 0.2f * (1 - a);
      out.at(x, y, 1) = 0.8f * b + 0.2f * (1 - b);
      out.at(x, y, 2) = 0.2f;
    }
  return out;
}

}  // namespace

Image fit_comparison_view(const SubjectFit& est, const SubjectFit& truth, int view, int height) {
  const BodyState se = body_forward(*est.model, est.params);
  const BodyState st = body_forward(*truth.model, truth.params);
  if (view == 2) {
    Camera ce = est.camera;
    const double s = double(truth.camera.width) / ce.width;
    ce.fx *= s, ce.fy *= s, ce.cx *= s, ce.cy *= s;
    ce.width = truth.camera.width, ce.height = truth.camera.height;
    return compose(body_mask(*est.model, se, ce), body_mask(*truth.model, st, truth.camera));
  }
  auto to_cam = [](const Eigen::MatrixXd& V, const Camera& c) {
    Eigen::MatrixXd out(V.rows(), 3);
    for (long i = 0; i < V.rows(); ++i) out.row(i) = c.to_camera(V.row(i).transpose()).transpose();
    return out;
  };
  // Both bodies in camera coordinates; align the estimate's pelvis to the truth's (depth is
  // not what this picture is about: the pose is).
  Eigen::MatrixXd Ve = to_cam(se.vertices, est.camera), Vt = to_cam(st.vertices, truth.camera);
  const Eigen::RowVector3d shift =
      truth.camera.to_camera(st.joints.row(0).transpose()).transpose() -
      est.camera.to_camera(se.joints.row(0).transpose()).transpose();
  Ve.rowwise() += shift;
  const Eigen::Vector3d centre = Vt.colwise().mean().transpose();
  // A camera in camera-space coordinates: view 0 looks along +z, view 1 along -x (from the
  // subject's right as the camera sees it).
  const double dist = 4.0;
  const Eigen::Vector3d dir = view == 0 ? Eigen::Vector3d(0, 0, 1) : Eigen::Vector3d(-1, 0, 0);
  const Eigen::Vector3d eye = centre - dist * dir;
  Camera c = Camera::look_at(eye, centre, Eigen::Vector3d(0, -1, 0), height * 2 / 3, height,
                             height * 1.6, height * 1.6, height / 3.0, height / 2.0);
  MeshRenderOptions ro;
  ro.want_rgb = false;
  MeshRenderInput ri;
  ri.vertices = &Ve;
  ri.faces = &est.model->faces;
  const Image me = render_mesh(c, ri, ro).mask;
  ri.vertices = &Vt;
  ri.faces = &truth.model->faces;
  return compose(me, render_mesh(c, ri, ro).mask);
}

}  // namespace ks
