#include "motion/amass.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <map>

#include "core/error.hpp"
#include "core/rotation.hpp"
#include "io/npz.hpp"

namespace ks {

namespace {

// AMASS's Z-up world to kinesplat's Y-up: -90 degrees about X, (x, y, z) -> (x, z, -y).
Eigen::Matrix3d amass_to_world() {
  Eigen::Matrix3d C;
  C << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return C;
}

}  // namespace

Motion load_amass_npz(const std::string& path, int frames) {
  const NpzFile npz = read_npz(path);
  if (!npz.has("poses")) throw Error(path + ": not an AMASS motion (no \"poses\" array)");
  if (!npz.has("trans")) throw Error(path + ": AMASS motion without a \"trans\" array");
  const NpyArray& poses = npz.arrays.at("poses");
  const NpyArray& trans = npz.arrays.at("trans");
  if (!poses.is_float() || poses.shape.size() != 2)
    throw Error(path + ": \"poses\" must be a 2-D float array, got " + poses.shape_string());
  const int64_t N = poses.shape[0], D = poses.shape[1];
  if (D != 156 && D != 165 && D != 72)
    throw Error(path + ": \"poses\" has " + std::to_string(D) +
                " columns; expected 156 (SMPL+H), 165 (SMPL-X) or 72 (SMPL)");
  if (!trans.is_float() || trans.shape.size() != 2 || trans.shape[0] != N || trans.shape[1] != 3)
    throw Error(path + ": \"trans\" must be " + std::to_string(N) + " x 3, got " +
                trans.shape_string());
  if (N == 0) throw Error(path + ": the motion has no frames");
  // Every value, also of the frames the subsampling skips: a NaN anywhere is a corrupt file.
  for (const NpyArray* a : {&poses, &trans})
    for (int64_t i = 0; i < a->size(); ++i)
      if (!std::isfinite(a->as_double(i)))
        throw Error(path + ": non-finite value in \"" + (a == &poses ? "poses" : "trans") +
                    "\" (frame " + std::to_string(i / a->shape[1]) + ")");
  double fps = 30.0;
  for (const char* key : {"mocap_framerate", "mocap_frame_rate"})
    if (npz.has(key)) {
      const NpyArray& f = npz.arrays.at(key);
      if (f.size() != 1) throw Error(path + ": \"" + key + "\" must be a single number");
      fps = f.as_double(0);
      if (!(fps > 0) || !std::isfinite(fps))
        throw Error(path + ": \"" + std::string(key) + "\" must be positive");
      break;
    }
  const int stride = std::max(1, int(std::lround(fps / 30.0)));
  Motion m;
  m.name = std::filesystem::path(path).stem().string();
  m.fps = fps / stride;
  const Eigen::Matrix3d C = amass_to_world();
  Eigen::Vector3d t0 = Eigen::Vector3d::Zero();
  for (int64_t i = 0; i < N; i += stride) {
    if (frames > 0 && int(m.frames.size()) >= frames) break;
    auto P = [&](int64_t k) { return poses.as_double(i * D + k); };
    BodyParams b;
    Eigen::Vector3d go(P(0), P(1), P(2));
    Eigen::Vector3d t(trans.as_double(i * 3), trans.as_double(i * 3 + 1),
                      trans.as_double(i * 3 + 2));
    if (!go.allFinite() || !t.allFinite())
      throw Error(path + ": non-finite pose or translation at frame " + std::to_string(i));
    b.global_orient = matrix_to_axis_angle(C * axis_angle_to_matrix(go));
    t = C * t;
    if (m.frames.empty()) t0 = t;
    b.transl = t - t0;
    b.body_pose = Eigen::VectorXd::Zero(69);
    for (int k = 0; k < 63; ++k) b.body_pose[k] = P(3 + k);
    if (D == 72)
      for (int k = 63; k < 69; ++k) b.body_pose[k] = P(3 + k);
    int hand = -1;
    if (D == 156) hand = 66;
    if (D == 165) {
      b.jaw_pose = Eigen::Vector3d(P(66), P(67), P(68));
      b.leye_pose = Eigen::Vector3d(P(69), P(70), P(71));
      b.reye_pose = Eigen::Vector3d(P(72), P(73), P(74));
      hand = 75;
    }
    if (hand >= 0) {
      b.left_hand_pose.resize(45);
      b.right_hand_pose.resize(45);
      for (int k = 0; k < 45; ++k) {
        b.left_hand_pose[k] = P(hand + k);
        b.right_hand_pose[k] = P(hand + 45 + k);
      }
    }
    if (!b.body_pose.allFinite())
      throw Error(path + ": non-finite pose at frame " + std::to_string(i));
    m.frames.push_back(std::move(b));
  }
  return m;
}

void save_amass_npz(const std::string& path, const Motion& m) {
  if (m.frames.empty()) throw Error("writing " + path + ": the motion has no frames");
  const Eigen::Matrix3d C = amass_to_world();  // load_amass_npz's; here its transpose
  const int64_t N = int64_t(m.frames.size());
  Eigen::MatrixXd poses = Eigen::MatrixXd::Zero(N, 72), trans(N, 3);
  for (int64_t i = 0; i < N; ++i) {
    const BodyParams& b = m.frames[size_t(i)];
    const Eigen::Vector3d go = matrix_to_axis_angle(
        Eigen::Matrix3d(C.transpose() * axis_angle_to_matrix(b.global_orient)));
    poses.block<1, 3>(i, 0) = go.transpose();
    const int n = std::min<int>(69, int(b.body_pose.size()));
    for (int k = 0; k < n; ++k) poses(i, 3 + k) = b.body_pose[k];
    trans.row(i) = (C.transpose() * b.transl).transpose();
  }
  std::map<std::string, NpyArray> a;
  a["poses"] = NpyArray::from_matrix(poses);
  a["trans"] = NpyArray::from_matrix(trans);
  const double fps = m.fps;
  a["mocap_framerate"] = NpyArray::from_doubles({}, &fps);
  write_npz(path, a);
}

}  // namespace ks
