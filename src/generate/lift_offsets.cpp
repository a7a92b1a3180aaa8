#include "generate/lift_offsets.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>

#include "body/parts.hpp"
#include "core/error.hpp"
#include "fit/silhouette.hpp"
#include "mesh/trimesh.hpp"

namespace ks::lift {

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::RowMajor>;

constexpr double kNormalProbe = 0.01;   // metres along the normal: its direction in the image
constexpr double kMinDirection = 1e-3;  // pixels: shorter, the normal faces the camera
constexpr double kMarchStep = 0.5;      // pixels per step of the march along that direction
constexpr double kRimWeight = 1.0;      // a rim offset's weight (the unit of the others)
constexpr double kRegulariser = 1e-6;   // on the diagonal: vertices no term reaches stay 0

}  // namespace

std::vector<RimOffset> rim_offsets(const Eigen::MatrixXd& V, const Eigen::MatrixXd& N,
                                   const Camera& cam, const MeshRenderOutput& body,
                                   const Image& mask, const LiftOptions& o) {
  std::vector<RimOffset> out;
  for (const fit::RimVertex& rv : fit::rim_vertices(V, nullptr, cam, body, o.rim_depth_tolerance)) {
    const Eigen::Vector3d p = V.row(rv.index).transpose(), n = N.row(rv.index).transpose();
    const Eigen::Vector2d q = cam.project(p + kNormalProbe * n);
    Eigen::Vector2d dir = q - rv.uv;
    if (dir.norm() < kMinDirection) continue;  // the normal faces the camera: not a rim direction
    dir.normalize();
    const double px_per_m = cam.fx / rv.depth;
    const double out_px = o.max_offset * px_per_m, in_px = -o.min_offset * px_per_m;
    if (in_mask(mask, rv.uv.x(), rv.uv.y())) {
      // The mask's end within reach; a march that meets the body again first (a gap the mask
      // fills) or runs out of reach gives no value.
      double t = kMarchStep;
      bool left_body = false, ended = false;
      for (; t <= out_px; t += kMarchStep) {
        const Eigen::Vector2d a = rv.uv + t * dir;
        const int x = int(std::floor(a.x())), y = int(std::floor(a.y()));
        if (x < 0 || y < 0 || x >= mask.width || y >= mask.height) break;
        const bool on_body = body.mask.at(x, y, 0) >= 0.5f;
        if (!on_body) left_body = true;
        if (left_body && on_body) break;
        if (mask.at(x, y, 0) < 0.5f) {
          ended = true;
          break;
        }
      }
      if (!ended) continue;
      out.push_back({rv.index, t / px_per_m});
    } else {
      double t = kMarchStep;
      for (; t <= in_px; t += kMarchStep) {
        const Eigen::Vector2d a = rv.uv - t * dir;
        if (in_mask(mask, a.x(), a.y())) break;
      }
      out.push_back({rv.index, -std::min(t, in_px) / px_per_m});
    }
  }
  return out;
}

OffsetTargets offset_targets(const std::vector<RimOffset>& rim,
                             const std::vector<uint8_t>& under_tube, const LiftBody& body,
                             const Camera& cam, const LiftOptions& o) {
  const long N = body.vertices();
  const Eigen::MatrixXd& V0 = body.person.rest;
  const auto under = [&](long i) { return !under_tube.empty() && under_tube[size_t(i)]; };
  OffsetTargets t;
  const auto add = [&](long i, double value, double w) {
    t.targets.emplace_back(int(i), value);
    t.weights.push_back(w);
  };
  for (const RimOffset& r : rim)
    if (!under(r.vertex)) add(r.vertex, r.offset, kRimWeight);  // the tube stands for the cloth
  for (long i = 0; i < N; ++i)
    if (under(i)) add(i, 0.0, o.w_under_tube_zero);
  // Surfaces the photo sees face-on (or from behind) show no standoff in the silhouette: a weak
  // pull towards the body there, so that the sides' standoff is not carried onto chest and back.
  if (o.w_facing_zero > 0) {
    const Eigen::Vector3d eye = cam.centre();
    for (long i = 0; i < N; ++i) {
      const Eigen::Vector3d p = body.posed.vertices.row(i).transpose();
      const double c = body.posed_normals.row(i).dot((p - eye).normalized());
      if (c * c > o.facing_min_cos * o.facing_min_cos) add(i, 0.0, o.w_facing_zero * c * c);
    }
  }
  // The face has no clothes: soft zeros on the front of the head below the brows.
  for (long i = 0; i < N; ++i)
    if (body.person.labels[size_t(i)] == kHeadNeck &&
        body.rest_normals(i, 2) > o.face_min_normal_z && V0(i, 1) < body.head.brow &&
        V0(i, 1) > body.head.neck + o.face_above_neck)
      add(i, 0.0, o.w_face_zero);
  return t;
}

Eigen::VectorXd smooth_offsets(const SpMat& stencil, const BodyModel& m,
                               const OffsetTargets& targets, const LiftOptions& o) {
  const auto& tg = targets.targets;
  const auto& tw = targets.weights;
  const int n0 = m.num_vertices();
  std::vector<Eigen::Triplet<double>> tr;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n0);
  // Data: sum_t w_t (S_t . x - v_t)^2.
  {
    SpMat A(long(tg.size()), n0);
    std::vector<Eigen::Triplet<double>> at;
    for (size_t t = 0; t < tg.size(); ++t) {
      const double sw = std::sqrt(tw[t]);
      for (SpMat::InnerIterator it(stencil, tg[t].first); it; ++it)
        at.emplace_back(int(t), int(it.col()), sw * it.value());
    }
    A.setFromTriplets(at.begin(), at.end());
    Eigen::VectorXd b(long(tg.size()));
    for (size_t t = 0; t < tg.size(); ++t) b(long(t)) = std::sqrt(tw[t]) * tg[t].second;
    const SpMat AtA = SpMat(A.transpose() * A);
    rhs = A.transpose() * b;
    for (int k = 0; k < AtA.outerSize(); ++k)
      for (SpMat::InnerIterator it(AtA, k); it; ++it)
        tr.emplace_back(int(it.row()), int(it.col()), it.value());
  }
  // Smoothness: sum over edges w_e (x_a - x_b)^2, w_e = offset_smoothness within a part, times
  // offset_cross_part across.
  for (const auto& [a, b] : mesh_edges(m.faces)) {
    const double w =
        o.offset_smoothness *
        (m.part_labels[size_t(a)] == m.part_labels[size_t(b)] ? 1.0 : o.offset_cross_part);
    tr.emplace_back(a, a, w);
    tr.emplace_back(b, b, w);
    tr.emplace_back(a, b, -w);
    tr.emplace_back(b, a, -w);
  }
  for (int i = 0; i < n0; ++i) tr.emplace_back(i, i, kRegulariser);
  Eigen::SparseMatrix<double> M(n0, n0);
  M.setFromTriplets(tr.begin(), tr.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(M);
  if (solver.info() != Eigen::Success) throw Error("lift: the offset system could not be solved");
  Eigen::VectorXd offset = stencil * Eigen::VectorXd(solver.solve(rhs));
  for (long i = 0; i < offset.size(); ++i)
    offset(i) = std::clamp(offset(i), o.min_offset, o.max_offset);
  return offset;
}

}  // namespace ks::lift
