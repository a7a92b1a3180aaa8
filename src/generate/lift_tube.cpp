#include "generate/lift_tube.hpp"

#include "body/parts.hpp"
#include "mesh/trimesh.hpp"
#include "reconstruct/garment/skinning.hpp"

namespace ks::lift {

LiftTube lift_tube(const Image& mask, const LiftBody& body, const Camera& cam,
                   const LiftOptions& o) {
  const SynthPerson& P = body.person;
  const Eigen::MatrixXd& joints = body.posed.joints;
  LiftTube t;
  t.joints = skirt_joints(*P.model);
  const SkirtJoints& sj = t.joints;
  const auto project_mid = [&](int a, int b) {
    return cam.project(0.5 * (joints.row(a) + joints.row(b)).transpose());
  };
  t.garment = detect_photo_garment(mask, body.render.mask, body.render.labels,
                                   project_mid(sj.left_hip, sj.right_hip),
                                   project_mid(sj.left_knee, sj.right_knee), cam.fx,
                                   cam.to_camera(joints.row(sj.pelvis).transpose()).z(),
                                   o.clothing_allowance, o.min_garment_hem);
  t.skirt = o.skirt;
  if (t.garment.spans_legs && o.garment) {
    t.skirt.hem = t.garment.hem;
    t.skirt.half_width = t.garment.half_width;
    t.proxy = make_skirt_proxy(P.rest, P.labels, body.rest_state.rest_joints, sj,
                               mean_face_edge_length(P.rest, P.faces), t.skirt);
  }
  return t;
}

std::vector<uint8_t> under_tube(const LiftTube& tube, const LiftBody& body) {
  if (!tube.present()) return {};
  const long N = body.vertices();
  std::vector<uint8_t> out(size_t(N), 0);
  for (long i = 0; i < N; ++i)
    out[size_t(i)] = skirt_encloses(tube.proxy, body.person.rest.row(i).transpose(),
                                    body.person.labels[size_t(i)]);
  return out;
}

void attach_tube(SynthPerson& P, const LiftTube& tube, const LiftBody& body) {
  if (!tube.present()) return;
  using SpMat = Eigen::SparseMatrix<double, Eigen::RowMajor>;
  const SkirtProxy& proxy = tube.proxy;
  const long N = body.vertices(), T = proxy.V.rows(), M = P.faces.rows();
  std::vector<int> j4(4 * size_t(N + T), 0);
  std::vector<float> w4(4 * size_t(N + T), 0.f);
  for (long i = 0; i < N; ++i)
    for (int k = 0; k < 4; ++k) {
      j4[4 * size_t(i) + k] = P.skin_joints(i, k);
      w4[4 * size_t(i) + k] = float(P.skin_weights(i, k));
    }
  const std::vector<int> body_j(j4.begin(), j4.begin() + 4 * N);
  const std::vector<float> body_w(w4.begin(), w4.begin() + 4 * N);
  make_skirt_skinning(proxy, tube.joints, tube.skirt, body.person.rest, body.person.labels, body_j,
                      body_w, true)
      .apply({tube.skirt.follow}, j4, w4);
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

}  // namespace ks::lift
