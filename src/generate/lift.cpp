#include "generate/lift.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <numeric>

#include <opencv2/imgproc.hpp>
#include "body/keypoints.hpp"
#include "body/parts.hpp"
#include "body/skin_weights.hpp"

#include "core/error.hpp"
#include "fit/silhouette.hpp"
#include "generate/photo_garment.hpp"
#include "mesh/point_grid.hpp"
#include "mesh/trimesh.hpp"
#include "meshrender/meshrender.hpp"
#include "reconstruct/garment/proxy.hpp"
#include "reconstruct/garment/skinning.hpp"

namespace ks {

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// Bilinear sample of an image at image point (u, v) (pixel centres at integer + 0.5).
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

bool in_mask(const Image& m, double u, double v) {
  const int x = int(std::floor(u)), y = int(std::floor(v));
  return x >= 0 && y >= 0 && x < m.width && y < m.height && m.at(x, y, 0) >= 0.5f;
}

// Silhouette offsets (metres along the vertex normals) at the body's rim vertices: from each rim
// vertex, along its normal's direction in the image, how far the photo's mask goes on (or, when
// the vertex is already outside the mask, how far inside the mask begins). A march that meets the
// body again before the mask ends (a gap the mask fills, e.g. an arm against the torso) gives no
// value.
struct RimOffset {
  int vertex;
  double offset;
};
std::vector<RimOffset> rim_offsets(const Eigen::MatrixXd& V, const Eigen::MatrixXd& N,
                                   const Camera& cam, const MeshRenderOutput& body,
                                   const Image& mask, const LiftOptions& o) {
  std::vector<RimOffset> out;
  for (const fit::RimVertex& rv : fit::rim_vertices(V, nullptr, cam, body, 0.02)) {
    const Eigen::Vector3d p = V.row(rv.index).transpose(), n = N.row(rv.index).transpose();
    const Eigen::Vector2d q = cam.project(p + 0.01 * n);
    Eigen::Vector2d dir = q - rv.uv;
    if (dir.norm() < 1e-3) continue;  // the normal faces the camera: not a rim direction
    dir.normalize();
    const double px_per_m = cam.fx / rv.depth;
    const double out_px = o.max_offset * px_per_m, in_px = -o.min_offset * px_per_m;
    const double step = 0.5;
    if (in_mask(mask, rv.uv.x(), rv.uv.y())) {
      // The mask's end within reach; a march that meets the body again first (a gap the mask
      // fills) or runs out of reach gives no value.
      double t = step;
      bool left_body = false, ended = false;
      for (; t <= out_px; t += step) {
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
      double t = step;
      for (; t <= in_px; t += step) {
        const Eigen::Vector2d a = rv.uv - t * dir;
        if (in_mask(mask, a.x(), a.y())) break;
      }
      out.push_back({rv.index, -std::min(t, in_px) / px_per_m});
    }
  }
  return out;
}

// Smooth offsets over the body: least squares on the base mesh (unknowns per base vertex,
// carried to the subdivided mesh by the stencil) fitting the rim values and soft zeros, with a
// Laplacian that is weak across body parts (hair does not spill onto the shoulders).
Eigen::VectorXd smooth_offsets(const SpMat& S, const BodyModel& m,
                               const std::vector<std::pair<int, double>>& targets,
                               const std::vector<double>& target_weights) {
  const int n0 = m.num_vertices();
  std::vector<Eigen::Triplet<double>> tr;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n0);
  // Data: sum_t w_t (S_t . x - v_t)^2.
  {
    SpMat A(long(targets.size()), n0);
    std::vector<Eigen::Triplet<double>> at;
    for (size_t t = 0; t < targets.size(); ++t) {
      const double sw = std::sqrt(target_weights[t]);
      for (SpMat::InnerIterator it(S, targets[t].first); it; ++it)
        at.emplace_back(int(t), int(it.col()), sw * it.value());
    }
    A.setFromTriplets(at.begin(), at.end());
    Eigen::VectorXd b(long(targets.size()));
    for (size_t t = 0; t < targets.size(); ++t)
      b(long(t)) = std::sqrt(target_weights[t]) * targets[t].second;
    const SpMat AtA = SpMat(A.transpose() * A);
    rhs = A.transpose() * b;
    for (int k = 0; k < AtA.outerSize(); ++k)
      for (SpMat::InnerIterator it(AtA, k); it; ++it)
        tr.emplace_back(int(it.row()), int(it.col()), it.value());
  }
  // Smoothness: lambda sum over edges w_e (x_a - x_b)^2, w_e = 1 within a part, 0.05 across.
  const double lambda = 0.5;
  for (const auto& [a, b] : mesh_edges(m.faces)) {
    const double w = lambda * (m.part_labels[size_t(a)] == m.part_labels[size_t(b)] ? 1.0 : 0.05);
    tr.emplace_back(a, a, w);
    tr.emplace_back(b, b, w);
    tr.emplace_back(a, b, -w);
    tr.emplace_back(b, a, -w);
  }
  for (int i = 0; i < n0; ++i) tr.emplace_back(i, i, 1e-6);
  Eigen::SparseMatrix<double> M(n0, n0);
  M.setFromTriplets(tr.begin(), tr.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(M);
  if (solver.info() != Eigen::Success) throw Error("lift: the offset system could not be solved");
  return solver.solve(rhs);
}

// Index of each vertex's mirror image (x -> -x about the pelvis), -1 if none within `radius`.
std::vector<int> mirror_left_right(const Eigen::MatrixXd& V, double cx, double radius) {
  const PointGrid grid(V, radius);
  std::vector<int> out(size_t(V.rows()), -1);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < V.rows(); ++i)
    out[size_t(i)] = grid.nearest(Eigen::Vector3d(2 * cx - V(i, 0), V(i, 1), V(i, 2)), radius);
  return out;
}

// Index of each vertex's front/back mirror: the point reflected in depth (z) about the closest
// point of its main bone (the joint with the largest skin weight to its first child, or from its
// parent for a leaf), on the other face of the body.
std::vector<int> mirror_front_back(const Eigen::MatrixXd& V, const Eigen::MatrixXd& normals,
                                   const SynthPerson& P, const Eigen::MatrixXd& joints,
                                   double radius) {
  const std::vector<int>& parents = P.model->parents;
  const int J = int(parents.size());
  std::vector<int> child(static_cast<size_t>(J), -1);
  for (int j = J - 1; j > 0; --j) child[size_t(parents[size_t(j)])] = j;
  const PointGrid grid(V, radius);
  std::vector<int> out(size_t(V.rows()), -1);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < V.rows(); ++i) {
    const int j = P.skin_joints(i, 0);
    Eigen::Vector3d a = joints.row(j).transpose(), b;
    if (child[size_t(j)] >= 0)
      b = joints.row(child[size_t(j)]).transpose();
    else
      b = a + (a - joints.row(std::max(0, parents[size_t(j)])).transpose());
    const Eigen::Vector3d p = V.row(i).transpose(), ab = b - a;
    const double t =
        ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    const double cz = a.z() + t * ab.z();
    const Eigen::Vector3d q(p.x(), p.y(), 2 * cz - p.z());
    const double nz = normals(i, 2);
    out[size_t(i)] = grid.nearest(q, radius, [&](int k) { return normals(k, 2) * nz < 0.0; });
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

SynthPerson lift_person(const Image& photo, const Image& mask, const SubjectFit& fit,
                        const LiftOptions& o, LiftReport* report) {
  const Camera& cam = fit.camera;
  if (photo.width != cam.width || photo.height != cam.height)
    throw Error("lift: the photo is " + std::to_string(photo.width) + "x" +
                std::to_string(photo.height) + ", the fit's camera " + std::to_string(cam.width) +
                "x" + std::to_string(cam.height));
  if (mask.width != photo.width || mask.height != photo.height)
    throw Error("lift: the mask's size differs from the photo's");
  const BodyModel& model = *fit.model;
  SynthPerson P =
      body_mesh_person(fit.model, fit.body_model, fit.params.betas, o.subdivision_levels);
  const long N = P.rest.rows();
  const Eigen::MatrixXd V0 = P.rest;
  const Eigen::MatrixXd rest_normals = vertex_normals(V0, P.faces);

  // 1. Silhouette offsets at the rim of the posed body, smoothed over the whole body.
  const PosedPerson posed0 = pose_synth_person(P, fit.params);
  const Eigen::MatrixXd N0 = vertex_normals(posed0.vertices, P.faces);
  const MeshRenderOutput body0 = render_depth(posed0.vertices, P.faces, cam, &P.labels);
  BodyParams zero;
  zero.betas = fit.params.betas;
  zero.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
  const BodyState rest_state = body_forward(model, zero);

  // Cloth across the legs (skirts, dresses, coats): a tube of its own (reconstruct's skirt proxy
  // around the hips and thighs, down to the hem the photo shows, as wide as it shows).
  const SkirtJoints sj = skirt_joints(model);
  const auto project_mid = [&](int a, int b) {
    return cam.project(0.5 * (posed0.joints.row(a) + posed0.joints.row(b)).transpose());
  };
  const PhotoGarment garment =
      detect_photo_garment(mask, body0.mask, body0.labels, project_mid(sj.left_hip, sj.right_hip),
                           project_mid(sj.left_knee, sj.right_knee), cam.fx,
                           cam.to_camera(posed0.joints.row(sj.pelvis).transpose()).z(),
                           o.clothing_allowance, o.min_garment_hem);
  SkirtOptions skirt = o.skirt;
  SkirtProxy proxy;
  if (garment.spans_legs && o.garment) {
    skirt.hem = garment.hem;
    skirt.half_width = garment.half_width;
    double edge = 0;
    const auto edges = mesh_edges(P.faces);
    for (const auto& [a, b] : edges) edge += (V0.row(a) - V0.row(b)).norm();
    proxy = make_skirt_proxy(V0, P.labels, rest_state.rest_joints, sj, edge / edges.size(), skirt);
  }
  const bool has_skirt = proxy.V.rows() > 0;
  auto under_skirt = [&](long i) {
    return has_skirt && skirt_encloses(proxy, V0.row(i).transpose(), P.labels[size_t(i)]);
  };

  const std::vector<RimOffset> rim = rim_offsets(posed0.vertices, N0, cam, body0, mask, o);
  std::vector<std::pair<int, double>> targets;
  std::vector<double> tw;
  for (const RimOffset& r : rim) {
    if (under_skirt(r.vertex)) continue;  // the tube stands for the cloth there
    targets.emplace_back(r.vertex, r.offset);
    tw.push_back(1.0);
  }
  for (long i = 0; i < N && has_skirt; ++i)
    if (under_skirt(i)) {
      targets.emplace_back(int(i), 0.0);
      tw.push_back(0.3);
    }
  // Surfaces the photo sees face-on (or from behind) show no standoff in the silhouette: a weak
  // pull towards the body there, so that the sides' standoff is not carried onto chest and back.
  if (o.w_facing_zero > 0) {
    const Eigen::Vector3d eye0 = cam.centre();
    for (long i = 0; i < N; ++i) {
      const Eigen::Vector3d p = posed0.vertices.row(i).transpose();
      const double c = N0.row(i).dot((p - eye0).normalized());
      if (c * c > 0.25) {
        targets.emplace_back(int(i), 0.0);
        tw.push_back(o.w_facing_zero * c * c);
      }
    }
  }
  // The face has no clothes: soft zeros on the front of the head below the brows.
  const auto kp_src = body25_sources(model);
  const Eigen::MatrixXd kp_rest =
      body25_points(kp_src, rest_state.rest_joints, rest_state.rest_vertices);
  const double brow_y = kp_rest(body25::kREye, 1) + 0.03;
  for (long i = 0; i < N; ++i)
    if (P.labels[size_t(i)] == kHeadNeck && rest_normals(i, 2) > 0.3 && V0(i, 1) < brow_y &&
        V0(i, 1) > rest_state.rest_joints(12, 1) + 0.03) {
      targets.emplace_back(int(i), 0.0);
      tw.push_back(0.3);
    }
  Eigen::VectorXd offset = Eigen::VectorXd::Zero(N);
  if (!rim.empty()) {
    const Eigen::VectorXd x0 = smooth_offsets(P.stencil, model, targets, tw);
    offset = P.stencil * x0;
    for (long i = 0; i < N; ++i) offset(i) = std::clamp(offset(i), o.min_offset, o.max_offset);
  }
  P.rest = V0 + rest_normals.cwiseProduct(offset.replicate(1, 3));
  if (has_skirt) {
    // The body under the tube moves with it; the tube joins the mesh as a component of its own,
    // both skinned as the skirt (reconstruct/garment/skinning.hpp) at its starting follow.
    const long T = proxy.V.rows(), M = P.faces.rows();
    std::vector<int> j4(4 * size_t(N + T), 0);
    std::vector<float> w4(4 * size_t(N + T), 0.f);
    for (long i = 0; i < N; ++i)
      for (int k = 0; k < 4; ++k) {
        j4[4 * size_t(i) + k] = P.skin_joints(i, k);
        w4[4 * size_t(i) + k] = float(P.skin_weights(i, k));
      }
    const std::vector<int> body_j(j4.begin(), j4.begin() + 4 * N);
    const std::vector<float> body_w(w4.begin(), w4.begin() + 4 * N);
    make_skirt_skinning(proxy, sj, skirt, V0, P.labels, body_j, body_w, true)
        .apply({skirt.follow}, j4, w4);
    P.rest.conservativeResize(N + T, 3);
    P.rest.bottomRows(T) = proxy.V;
    P.faces.conservativeResize(M + proxy.F.rows(), 3);
    P.faces.bottomRows(proxy.F.rows()) = proxy.F.array() + int(N);
    P.labels.resize(size_t(N + T), kHips);
    P.skin_joints.conservativeResize(N + T, 4);
    P.skin_weights.conservativeResize(N + T, 4);
    for (long i = 0; i < N + T; ++i)
      for (int k = 0; k < 4; ++k) {
        P.skin_joints(i, k) = j4[4 * size_t(i) + k];
        P.skin_weights(i, k) = w4[4 * size_t(i) + k];
      }
    SpMat S(N + T, P.stencil.cols());  // the tube has no body-model source (no correctives)
    std::vector<Eigen::Triplet<double>> st;
    for (int r = 0; r < P.stencil.outerSize(); ++r)
      for (SpMat::InnerIterator it(P.stencil, r); it; ++it)
        st.emplace_back(r, int(it.col()), it.value());
    S.setFromTriplets(st.begin(), st.end());
    P.stencil = S;
  }
  const long Nb = N;  // body vertices (the tube's follow)
  const long Nall = P.rest.rows();
  const Eigen::MatrixXd Vr = P.rest;
  const Eigen::MatrixXd Vr_normals = vertex_normals(Vr, P.faces);

  // 2. Colour from the photo where it sees the surface, inside the mask's outline by a couple of
  // pixels (the outline's pixels mix the person with the background).
  Image inner = mask;
  {
    const int r = std::max(1, int(std::lround(std::max(cam.width, cam.height) / 400.0)));
    cv::Mat m(mask.height, mask.width, CV_32FC1, const_cast<float*>(mask.data.data()));
    cv::Mat e(inner.height, inner.width, CV_32FC1, inner.data.data());
    cv::erode(m, e, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
  }
  const PosedPerson posed = pose_synth_person(P, fit.params);
  const Eigen::MatrixXd Np = vertex_normals(posed.vertices, P.faces);
  const MeshRenderOutput depth = render_depth(posed.vertices, P.faces, cam);
  const Eigen::Vector3d eye = cam.centre();
  Eigen::MatrixXd seen_colour = Eigen::MatrixXd::Zero(Nall, 3);
  Eigen::VectorXd seen_w = Eigen::VectorXd::Zero(Nall);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < Nall; ++i) {
    const Eigen::Vector3d p = posed.vertices.row(i).transpose();
    const Eigen::Vector3d c = cam.to_camera(p);
    if (c.z() <= 0) continue;
    const double cosv = -Np.row(i).dot((p - eye).normalized());
    if (cosv < o.visible_cos) continue;
    const Eigen::Vector2d uv = cam.project_camera(c);
    const int x = int(std::floor(uv.x())), y = int(std::floor(uv.y()));
    if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
    if (c.z() > depth.depth.at(x, y, 0) + o.depth_tolerance) continue;
    if (!in_mask(inner, uv.x(), uv.y())) continue;
    // Weight: how squarely the camera sees the surface (smooth from visible_cos up).
    const double t = std::clamp((cosv - o.visible_cos) / (0.6 - o.visible_cos), 0.0, 1.0);
    seen_w(i) = t * t * (3 - 2 * t);
    seen_colour.row(i) = sample_rgb(photo, uv.x(), uv.y()).transpose();
  }

  // 3. Mirrors for what the photo does not see.
  const double spacing = [&] {
    double s = 0;
    const auto edges = mesh_edges(P.faces);
    for (size_t e = 0; e < edges.size(); e += 37)
      s += (Vr.row(edges[e].first) - Vr.row(edges[e].second)).norm();
    return s / double((edges.size() + 36) / 37);
  }();
  const double radius = 4.0 * spacing;
  std::vector<int> lr, fb;
  if (o.mirror_left_right) lr = mirror_left_right(Vr, rest_state.rest_joints(0, 0), radius);
  if (o.mirror_front_back)
    fb = mirror_front_back(Vr, Vr_normals, P, rest_state.rest_joints, 3.0 * radius);
  // The hair's colour: the median photo colour of the seen crown (head vertices above the brows).
  Eigen::Vector3d hair = Eigen::Vector3d::Zero();
  {
    std::vector<double> ch[3];
    for (long i = 0; i < Nall; ++i)
      if (i < Nb && P.labels[size_t(i)] == kHeadNeck && V0(i, 1) > brow_y + 0.02 && seen_w(i) > 0.3)
        for (int k = 0; k < 3; ++k) ch[k].push_back(seen_colour(i, k));
    for (int k = 0; k < 3; ++k) hair(k) = median(ch[k]);
  }
  const double hairline_y = kp_rest(body25::kNose, 1) - 0.04;
  // The nape's colour: what the photo shows at the sides of the head and neck at that height
  // (long hair hangs there; else the neck's skin).
  Eigen::Vector3d nape_colour = hair;
  {
    std::vector<double> ch[3];
    for (long i = 0; i < Nb; ++i)
      if (P.labels[size_t(i)] == kHeadNeck && std::abs(rest_normals(i, 0)) > 0.6 &&
          std::abs(rest_normals(i, 2)) < 0.4 && seen_w(i) > 0.2 && V0(i, 1) < hairline_y &&
          V0(i, 1) > hairline_y - 0.1)
        for (int k = 0; k < 3; ++k) ch[k].push_back(seen_colour(i, k));
    if (!ch[0].empty())
      for (int k = 0; k < 3; ++k) nape_colour(k) = median(ch[k]);
  }
  Eigen::MatrixXd colour(Nall, 3);
  Eigen::VectorXd weight(Nall);
  int n_seen = 0, n_mirror = 0;
#pragma omp parallel for schedule(static) reduction(+ : n_seen, n_mirror)
  for (long i = 0; i < Nall; ++i) {
    const double ws = seen_w(i);
    Eigen::Vector3d acc = ws * seen_colour.row(i).transpose();
    double wsum = ws;
    const double rest_w = (1 - ws) * (1 - ws);
    if (!lr.empty() && lr[size_t(i)] >= 0) {
      const double w = 0.7 * rest_w * seen_w(lr[size_t(i)]);
      acc += w * seen_colour.row(lr[size_t(i)]).transpose();
      wsum += w;
    }
    // The back of the head, above the hairline at the nape (about the mouth's height).
    const bool head_back = o.hair_back && i < Nb && P.labels[size_t(i)] == kHeadNeck &&
                           rest_normals(i, 2) < -0.3 && V0(i, 1) > hairline_y;
    // Below it, the nape in the colour the sides of the neck show (not the face mirrored: no
    // lips on the neck).
    const bool nape = o.hair_back && i < Nb && P.labels[size_t(i)] == kHeadNeck &&
                      rest_normals(i, 2) < -0.3 && !head_back;
    if (head_back || nape) {
      const double w = 0.5 * rest_w;
      acc += w * (head_back ? hair : nape_colour);
      wsum += w;
    } else if (!fb.empty() && fb[size_t(i)] >= 0 && !(i < Nb && P.labels[size_t(i)] == kHeadNeck)) {
      // (never the face mirrored onto the back of the head or the nape)
      const double w = 0.5 * rest_w * seen_w(fb[size_t(i)]);
      acc += w * seen_colour.row(fb[size_t(i)]).transpose();
      wsum += w;
    }
    weight(i) = wsum;
    if (wsum > 0)
      colour.row(i) = (acc / wsum).transpose();
    else
      colour.row(i).setZero();
    if (ws >= 0.5)
      ++n_seen;
    else if (wsum >= 0.05)
      ++n_mirror;
  }

  // 4. What is left: propagation over the surface from the coloured vertices, ring by ring.
  const auto adj = vertex_adjacency(P.faces, int(Nall));
  std::vector<uint8_t> known(size_t(Nall), 0);
  for (long i = 0; i < Nall; ++i) known[size_t(i)] = weight(i) >= 0.05;
  int n_diffused = 0;
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<int> front;
    for (long i = 0; i < Nall; ++i) {
      if (known[size_t(i)]) continue;
      for (int k : adj[size_t(i)])
        if (known[size_t(k)]) {
          front.push_back(int(i));
          break;
        }
    }
    std::vector<Eigen::Vector3d> val(front.size());
    for (size_t f = 0; f < front.size(); ++f) {
      Eigen::Vector3d s = Eigen::Vector3d::Zero();
      int c = 0;
      for (int k : adj[size_t(front[f])])
        if (known[size_t(k)]) {
          s += colour.row(k).transpose();
          ++c;
        }
      val[f] = s / std::max(1, c);
    }
    for (size_t f = 0; f < front.size(); ++f) {
      colour.row(front[f]) = val[f].transpose();
      known[size_t(front[f])] = 1;
      changed = true;
    }
    n_diffused += int(front.size());
  }
  // A few smoothing passes where the colour was not seen well (no seams at the fills' edges).
  for (int pass = 0; pass < o.unseen_smoothing; ++pass) {
    Eigen::MatrixXd next = colour;
#pragma omp parallel for schedule(static)
    for (long i = 0; i < Nall; ++i) {
      const double keep = std::min(1.0, o.unseen_smoothing > 3 ? seen_w(i) : weight(i));
      if (keep >= 0.99) continue;
      Eigen::Vector3d s = Eigen::Vector3d::Zero();
      for (int k : adj[size_t(i)]) s += colour.row(k).transpose();
      s /= std::max<size_t>(1, adj[size_t(i)].size());
      next.row(i) = (keep * colour.row(i).transpose() + (1 - keep) * s).transpose();
    }
    colour = next;
  }
  P.colors = colour.cwiseMax(0.0).cwiseMin(1.0);

  if (report) {
    report->vertices = int(Nall);
    report->seen = double(n_seen) / Nall;
    report->mirrored = double(n_mirror) / Nall;
    report->diffused = double(n_diffused) / Nall;
    report->garment = garment.summary;
    report->garment_vertices = int(Nall - Nb);
    report->rim_vertices = double(rim.size());
    std::vector<double> off(offset.data(), offset.data() + N);
    report->offset_median_m = median(off);
    report->offset_max_m = offset.size() ? offset.maxCoeff() : 0.0;
    report->hair_colour = hair;
  }
  return P;
}

}  // namespace ks
