#include "synth/person.hpp"

#include <algorithm>
#include <cmath>

#include "body/skin_weights.hpp"
#include "core/error.hpp"
#include "mesh/trimesh.hpp"
#include "motion/motion.hpp"
#include "synth/keypoints.hpp"
#include "synth/skirt.hpp"

namespace ks {

namespace {

using Vec3 = Eigen::Vector3d;

}  // namespace

BodyParams synth_params(const SynthPerson& person, const BodyParams& pose) {
  BodyParams p = pose;
  p.betas = person.betas;
  adapt_body_pose(p, person.model->num_body_pose_joints());
  return p;
}

SynthPerson body_mesh_person(std::shared_ptr<const BodyModel> model, const std::string& body_model,
                             const Eigen::VectorXd& betas, int levels) {
  if (!model) throw Error("body mesh: no body model");
  const BodyModel& m = *model;
  if (int(m.part_labels.size()) != m.num_vertices())
    throw Error("body mesh: the body model has no part labels");
  SynthPerson P;
  P.model = model;
  P.body_model = body_model;
  P.betas = betas;
  BodyParams zero;
  zero.betas = betas;
  zero.body_pose = Eigen::VectorXd::Zero(3 * m.num_body_pose_joints());
  const BodyState st = body_forward(m, zero);
  const Subdivision sd = subdivide(TriMesh{st.rest_vertices, m.faces}, levels, true);
  P.rest = sd.mesh.V;
  P.faces = sd.mesh.F;
  P.stencil = sd.S;
  P.labels = carry_labels(sd.S, m.part_labels);
  const Eigen::MatrixXd W = sd.S * m.weights;
  P.skin_joints.resize(W.rows(), 4);
  P.skin_weights.resize(W.rows(), 4);
  top_k_skin_weights(W, 4, P.skin_joints.data(), P.skin_weights.data());
  P.colors = Eigen::MatrixXd::Constant(W.rows(), 3, 0.5);
  return P;
}

SynthPerson make_synth_person(std::shared_ptr<const BodyModel> model, const std::string& body_model,
                              uint64_t seed, const SynthOptions& options) {
  if (!model) throw Error("synth: no body model");
  const BodyModel& m = *model;
  if (m.num_joints() < 22) throw Error("synth: the body model needs SMPL's first 22 joints");
  if (int(m.part_labels.size()) != m.num_vertices())
    throw Error("synth: the body model has no part labels");
  if (options.subdivision_levels < 0 || options.subdivision_levels > 3)
    throw Error("synth: subdivision levels must be in 0..3");
  SynthPerson P;
  P.model = model;
  P.body_model = body_model;
  P.seed = seed;
  SynthRng rng(seed);
  // Body shape: the first coefficients vary most.
  const int nb = std::min(m.num_betas, 10);
  P.betas = Eigen::VectorXd::Zero(nb);
  for (int k = 0; k < nb; ++k)
    P.betas[k] = std::clamp(rng.normal() * (k < 2 ? 0.9 : 0.5), -2.0, 2.0);
  P.appearance = random_appearance(rng);

  BodyParams zero;
  zero.betas = P.betas;
  zero.body_pose = Eigen::VectorXd::Zero(3 * m.num_body_pose_joints());
  const BodyState st = body_forward(m, zero);
  {
    SynthPerson body = body_mesh_person(model, body_model, P.betas, options.subdivision_levels);
    P.faces = std::move(body.faces);
    P.stencil = std::move(body.stencil);
    P.labels = std::move(body.labels);
    P.skin_joints = std::move(body.skin_joints);
    P.skin_weights = std::move(body.skin_weights);
    P.rest = std::move(body.rest);
  }

  const Eigen::MatrixXd V0 = P.rest;
  const long N = V0.rows();
  const Eigen::MatrixXd normals = vertex_normals(V0, P.faces);
  const Landmarks L = find_landmarks(V0, P.labels, st.rest_joints);
  P.colors.resize(N, 3);
  P.rest.resize(N, 3);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < N; ++i) {
    Vec3 c;
    double d;
    const Vec3 p = V0.row(i).transpose(), n = normals.row(i).transpose();
    shade_point(P.appearance, L, p, n, P.labels[size_t(i)], c, d);
    P.colors.row(i) = c.transpose();
    P.rest.row(i) = (p + d * n).transpose();
  }

  if (P.appearance.bottom_kind == "skirt") add_skirt(P, L, V0);

  assign_keypoint_sources(P, V0, normals, L);
  return P;
}

PosedPerson pose_synth_person(const SynthPerson& person, const BodyParams& pose) {
  const BodyState st = body_forward(*person.model, synth_params(person, pose));
  PosedPerson out;
  out.joints = st.joints;
  Eigen::MatrixXd offsets;
  const bool correctives = !st.pose_offsets.isZero(0);
  if (correctives) offsets = person.stencil * st.pose_offsets;
  out.vertices = skin_points(person.rest, correctives ? &offsets : nullptr, person.skin_joints,
                             person.skin_weights, st.transforms);
  return out;
}

MeshRenderOutput render_synth(const SynthPerson& person, const PosedPerson& posed,
                              const Camera& camera, int supersample,
                              const Eigen::Vector3d& background, bool lighting) {
  MeshRenderInput in;
  in.vertices = &posed.vertices;
  in.faces = &person.faces;
  in.colors = &person.colors;
  in.labels = &person.labels;
  MeshRenderOptions opt;
  opt.supersample = supersample;
  opt.lighting = lighting;
  opt.background = background;
  opt.want_depth = true;
  opt.cull_backfaces = true;  // a closed surface seen from outside
  return render_mesh(camera, in, opt);
}

Camera synth_camera(const std::vector<const Eigen::MatrixXd*>& poses, double azimuth_deg, int width,
                    int height, double vfov_degrees, double fill) {
  if (poses.empty()) throw Error("synth_camera: no vertices");
  if (width <= 0 || height <= 0) throw Error("synth_camera: image size must be positive");
  Vec3 lo = Vec3::Constant(1e30), hi = Vec3::Constant(-1e30);
  for (const auto* P : poses)
    for (long i = 0; i < P->rows(); ++i) {
      lo = lo.cwiseMin(P->row(i).transpose());
      hi = hi.cwiseMax(P->row(i).transpose());
    }
  const Vec3 c = 0.5 * (lo + hi);
  const double az = azimuth_deg * M_PI / 180.0;
  const Vec3 dir(std::sin(az), 0.0, std::cos(az));
  const double f = 0.5 * height / std::tan(0.5 * vfov_degrees * M_PI / 180.0);
  const double radius = 0.5 * (hi - lo).norm();
  double dist = std::max(0.5 * (hi.y() - lo.y()) * f / (0.5 * fill * height), 0.1) + radius;
  Camera cam;
  for (int it = 0; it < 6; ++it) {
    cam = Camera::look_at(c + dist * dir, c, Vec3::UnitY(), width, height, f, f, 0.5 * width,
                          0.5 * height);
    // The most constraining vertex: the ratio of its offset from the centre to the allowed one.
    double worst = 0, worst_z = dist;
    for (const auto* P : poses)
      for (long i = 0; i < P->rows(); ++i) {
        const Vec3 q = cam.to_camera(P->row(i).transpose());
        if (q.z() <= 1e-6) {
          worst = 1e9;
          continue;
        }
        const double rv = std::abs(f * q.y() / q.z()) / (0.5 * fill * height);
        const double ru = std::abs(f * q.x() / q.z()) / (0.47 * width);
        const double r = std::max(rv, ru);
        if (r > worst) {
          worst = r;
          worst_z = q.z();
        }
      }
    if (worst >= 1e9) {
      dist *= 2;
      continue;
    }
    // That vertex sits at depth worst_z = dist - delta; scale its depth by `worst`.
    const double delta = dist - worst_z;
    const double nd = delta + worst_z * worst;
    if (std::abs(nd - dist) < 1e-6) break;
    dist = nd;
  }
  return Camera::look_at(c + dist * dir, c, Vec3::UnitY(), width, height, f, f, 0.5 * width,
                         0.5 * height);
}

}  // namespace ks
