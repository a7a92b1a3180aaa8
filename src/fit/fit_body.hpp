#pragma once
// The body as the fit sees it: a packed parameter vector (global orientation, body pose, the
// first betas, camera translation) and a forward model templated on the scalar, so that the same
// code gives values (double) and derivatives (ceres::Jet) of the posed joints, the BODY_25
// points and a subset of surface vertices. Hands, face and pose correctives stay at rest.
#include <Eigen/Core>
#include <array>
#include <vector>

#include "body/body_model.hpp"
#include "body/keypoints.hpp"
#include "body/posing.hpp"

namespace ks::fit {

// Offsets of the blocks in the packed parameter vector.
struct Layout {
  int orient = 0;  // 3: global orientation (axis-angle)
  int pose = 3;    // 3 * pose_joints: body_pose
  int pose_joints = 23;
  int betas = 0;  // num_betas
  int num_betas = 0;
  int cam = 0;  // 3: camera translation t (world -> camera: R0 X + t)
  int size = 0;
};

// The largest parameter vector the fit handles (SMPL: 3 + 69 + 10 + 3 = 85).
inline constexpr int kMaxParams = 96;

// What the forward model needs of a body model, precomputed once.
struct BodyData {
  Layout layout;
  std::vector<int> parents;  // J
  Eigen::MatrixXd J0;        // J x 3: joints of the template
  Eigen::MatrixXd Jdirs;     // 3J x num_betas: joint shape directions (row 3j + k)
  // The fit's vertex subset (silhouette samples): template, shape directions, top-4 skinning.
  std::vector<int> vertex_ids;                 // M
  Eigen::MatrixXd V0;                          // M x 3
  Eigen::MatrixXd Vdirs;                       // 3M x num_betas
  std::vector<std::array<int, 4>> skin_joint;  // M
  std::vector<std::array<double, 4>> skin_weight;
  std::array<Body25Source, kBody25Count> kp;  // BODY_25 sources; vertex ones are in vertex_ids
  std::array<int, kBody25Count> kp_slot{};    // index into vertex_ids for vertex keypoints
};

// Fixed camera rotation: a level camera on the body's +Z side looking towards -Z (image x = world
// X, image y = -world Y, depth = -world Z).
inline Eigen::Matrix3d camera_rotation() {
  return Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
}

// camera_rotation() * X + t: a world point in the camera's frame, the rotation applied as the
// sign flips it is (T = double or ceres::Jet).
template <class T>
Eigen::Matrix<T, 3, 1> to_camera(const Eigen::Matrix<T, 3, 1>& X, const Eigen::Matrix<T, 3, 1>& t) {
  return Eigen::Matrix<T, 3, 1>(X(0) + t(0), -X(1) + t(1), -X(2) + t(2));
}

// Builds the data for `model`: `num_betas` shape coefficients (at most the model's), every
// `vertex_stride`-th vertex as a silhouette sample, plus the BODY_25 surface vertices.
BodyData make_body_data(const BodyModel& model, int num_betas, int vertex_stride,
                        KeypointConvention convention = KeypointConvention::kJoints);

// The subset's vertices by linear blend skinning (forward's second half).
template <class T>
void skin_subset(const BodyData& d, const T* x, const std::vector<Eigen::Matrix<T, 3, 1>>& rest,
                 const std::vector<Eigen::Matrix<T, 3, 3>>& Rw,
                 const std::vector<Eigen::Matrix<T, 3, 1>>& joints,
                 std::vector<Eigen::Matrix<T, 3, 1>>& verts, const std::vector<int>* only) {
  const Layout& L = d.layout;
  const int J = int(d.parents.size());
  std::vector<Eigen::Matrix<T, 3, 1>>* vertices = &verts;
  (void)J;
  // Skinning: x -> Rw_j (x - rest_j) + joint_j.
  const int M = int(d.vertex_ids.size());
  vertices->resize(size_t(M));
  std::vector<Eigen::Matrix<T, 3, 1>> b(static_cast<size_t>(J));
  for (int j = 0; j < J; ++j) b[size_t(j)] = joints[size_t(j)] - Rw[size_t(j)] * rest[size_t(j)];
  const int count = only ? int(only->size()) : M;
#pragma omp parallel for schedule(static) if (count > 64)
  for (int i = 0; i < count; ++i) {
    const int m = only ? (*only)[size_t(i)] : i;
    Eigen::Matrix<T, 3, 1> v;
    for (int k = 0; k < 3; ++k) {
      T s = T(d.V0(m, k));
      for (int bb = 0; bb < L.num_betas; ++bb) s += T(d.Vdirs(3 * m + k, bb)) * x[L.betas + bb];
      v(k) = s;
    }
    Eigen::Matrix<T, 3, 1> out = Eigen::Matrix<T, 3, 1>::Zero();
    for (int q = 0; q < 4; ++q) {
      const double w = d.skin_weight[size_t(m)][size_t(q)];
      if (w == 0.0) continue;
      const int j = d.skin_joint[size_t(m)][size_t(q)];
      out += T(w) * (Rw[size_t(j)] * v + b[size_t(j)]);
    }
    (*vertices)[size_t(m)] = out;
  }
}

// Posed joints (J x 3, world) and the subset's vertices (M x 3, world) for the packed parameters
// `x`; with `only`, just those vertices of the subset (the others are left as they were).
// T = double or ceres::Jet.
// `keypoints` (optional): the BODY_25 points (their vertices must be among those computed).
template <class T>
void forward(const BodyData& d, const T* x, std::vector<Eigen::Matrix<T, 3, 1>>& joints,
             std::vector<Eigen::Matrix<T, 3, 1>>* vertices, const std::vector<int>* only = nullptr,
             std::vector<Eigen::Matrix<T, 3, 1>>* keypoints = nullptr) {
  const Layout& L = d.layout;
  const int J = int(d.parents.size());
  std::vector<Eigen::Matrix<T, 3, 1>> rest(static_cast<size_t>(J));
  for (int j = 0; j < J; ++j)
    for (int k = 0; k < 3; ++k) {
      T v = T(d.J0(j, k));
      for (int b = 0; b < L.num_betas; ++b) v += T(d.Jdirs(3 * j + k, b)) * x[L.betas + b];
      rest[size_t(j)](k) = v;
    }
  // The one forward kinematics (body/posing.hpp); hands and face at rest.
  MatrixX<T> rest_m(J, 3), pose(J, 3);
  for (int jj = 0; jj < J; ++jj)
    for (int k = 0; k < 3; ++k) {
      rest_m(jj, k) = rest[size_t(jj)](k);
      pose(jj, k) = jj == 0               ? x[L.orient + k]
                    : jj <= L.pose_joints ? x[L.pose + 3 * (jj - 1) + k]
                                          : T(0);
    }
  const PosedSkeleton<T> sk =
      forward_kinematics<T>(d.parents, rest_m, pose, Eigen::Matrix<T, 3, 1>::Zero());
  const std::vector<Eigen::Matrix<T, 3, 3>>& Rw = sk.rotations;
  joints = sk.origins;
  if (vertices) skin_subset(d, x, rest, Rw, joints, *vertices, only);
  if (keypoints) {
    keypoints->resize(kBody25Count);
    for (int k = 0; k < kBody25Count; ++k) {
      const Body25Source& s = d.kp[size_t(k)];
      Eigen::Matrix<T, 3, 1> p;
      if (s.vertex >= 0) {
        p = (*vertices)[size_t(d.kp_slot[size_t(k)])];
      } else {
        p = joints[size_t(s.joint)];
        if (s.joint2 >= 0) p = T(0.5) * (p + joints[size_t(s.joint2)]);
        if (s.frame >= 0 && !s.offset.isZero(0)) p += Rw[size_t(s.frame)] * s.offset.cast<T>();
      }
      (*keypoints)[size_t(k)] = p;
    }
  }
}

// The packed vector <-> body parameters and camera.
Eigen::VectorXd pack(const Layout& L, const BodyParams& p, const Eigen::Vector3d& cam_t);
BodyParams unpack_params(const Layout& L, const Eigen::VectorXd& x);
Eigen::Vector3d unpack_cam(const Layout& L, const Eigen::VectorXd& x);

}  // namespace ks::fit
