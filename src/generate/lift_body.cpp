#include "generate/lift_body.hpp"

#include <algorithm>
#include <cmath>

#include "body/joints.hpp"
#include "body/keypoints.hpp"
#include "mesh/trimesh.hpp"

namespace ks::lift {

LiftBody lift_body(const SubjectFit& fit, const LiftOptions& o) {
  const BodyModel& model = *fit.model;
  LiftBody b;
  b.person = body_mesh_person(fit.model, fit.body_model, fit.params.betas, o.subdivision_levels);
  b.rest_normals = vertex_normals(b.person.rest, b.person.faces);
  b.posed = pose_synth_person(b.person, fit.params);
  b.posed_normals = vertex_normals(b.posed.vertices, b.person.faces);
  b.render = render_depth(b.posed.vertices, b.person.faces, fit.camera, &b.person.labels);
  BodyParams zero;
  zero.betas = fit.params.betas;
  zero.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
  b.rest_state = body_forward(model, zero);
  const Eigen::MatrixXd kp_rest =
      body25_points(body25_sources(model), b.rest_state.rest_joints, b.rest_state.rest_vertices);
  b.head.brow = kp_rest(body25::kREye, 1) + o.face_above_eye;
  b.head.hairline = kp_rest(body25::kNose, 1) - o.hairline_below_nose;
  b.head.neck = b.rest_state.rest_joints(smpl_joint::kNeck, 1);
  return b;
}

bool in_mask(const Image& m, double u, double v) {
  const int x = int(std::floor(u)), y = int(std::floor(v));
  return x >= 0 && y >= 0 && x < m.width && y < m.height && m.at(x, y, 0) >= 0.5f;
}

Eigen::Vector3d sample_rgb(const Image& img, double u, double v) {
  const double x = std::clamp(u - 0.5, 0.0, img.width - 1.0);
  const double y = std::clamp(v - 0.5, 0.0, img.height - 1.0);
  const int x0 = std::min(int(x), img.width - 2 < 0 ? 0 : img.width - 2);
  const int y0 = std::min(int(y), img.height - 2 < 0 ? 0 : img.height - 2);
  const int x1 = std::min(x0 + 1, img.width - 1), y1 = std::min(y0 + 1, img.height - 1);
  const double fx = x - x0, fy = y - y0;
  Eigen::Vector3d c;
  for (int k = 0; k < 3; ++k) {
    const int ck = img.channels >= 3 ? k : 0;
    c(k) = (1 - fy) * ((1 - fx) * img.at(x0, y0, ck) + fx * img.at(x1, y0, ck)) +
           fy * ((1 - fx) * img.at(x0, y1, ck) + fx * img.at(x1, y1, ck));
  }
  return c;
}

}  // namespace ks::lift
