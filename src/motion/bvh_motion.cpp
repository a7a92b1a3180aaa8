#include "motion/bvh_motion.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>

#include "body/body_model.hpp"
#include "body/joints.hpp"
#include "core/error.hpp"
#include "core/rotation.hpp"

namespace ks {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Lower case, without a "prefix:" and without '_', ' ', '-', '.'.
std::string normalise(const std::string& name) {
  std::string s = name;
  const size_t colon = s.rfind(':');
  if (colon != std::string::npos) s = s.substr(colon + 1);
  std::string out;
  for (char c : s)
    if (c != '_' && c != ' ' && c != '-' && c != '.')
      out.push_back(char(std::tolower(static_cast<unsigned char>(c))));
  return out;
}

const char* const kSmplNames[24] = {
    "pelvis",     "left_hip",    "right_hip",    "spine1",      "left_knee",     "right_knee",
    "spine2",     "left_ankle",  "right_ankle",  "spine3",      "left_foot",     "right_foot",
    "neck",       "left_collar", "right_collar", "head",        "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist",   "right_wrist", "left_hand",     "right_hand"};

// Names (normalised) per SMPL joint for a convention; "" = not mapped. Left side only; the right
// side is derived ("left" -> "right", Poser's leading "l" -> "r").
struct Convention {
  const char* name;
  const char* joints[24];
};

const Convention kMixamo = {"Mixamo",
                            {"hips",
                             "leftupleg",
                             "",
                             "spine",
                             "leftleg",
                             "",
                             "spine1",
                             "leftfoot",
                             "",
                             "spine2",
                             "lefttoebase",
                             "",
                             "neck",
                             "leftshoulder",
                             "",
                             "head",
                             "leftarm",
                             "",
                             "leftforearm",
                             "",
                             "lefthand",
                             "",
                             "",
                             ""}};
const Convention kCmu = {"CMU",
                         {"hips",
                          "leftupleg",
                          "",
                          "lowerback",
                          "leftleg",
                          "",
                          "spine",
                          "leftfoot",
                          "",
                          "spine1",
                          "lefttoebase",
                          "",
                          "neck",
                          "leftshoulder",
                          "",
                          "head",
                          "leftarm",
                          "",
                          "leftforearm",
                          "",
                          "lefthand",
                          "",
                          "",
                          ""}};
const Convention kPoser = {
    "Poser", {"hip",    "lthigh", "",         "abdomen", "lshin", "",        "", "lfoot",
              "",       "chest",  "",         "",        "neck",  "lcollar", "", "head",
              "lshldr", "",       "lforearm", "",        "lhand", "",        "", ""}};

// Joint j's mirror: left_* <-> right_* (SMPL's indices).
int mirror(int j) {
  static const int m[24] = {0,  2,  1,  3,  5,  4,  6,  8,  7,  9,  11, 10,
                            12, 14, 13, 15, 17, 16, 19, 18, 21, 20, 23, 22};
  return m[j];
}

bool is_right(int j) {
  return std::string(kSmplNames[j]).rfind("right_", 0) == 0;
}

std::string convention_name(const Convention& c, int j, bool poser) {
  if (!is_right(j)) return c.joints[j];
  std::string left = c.joints[mirror(j)];
  if (left.empty()) return "";
  std::string out = poser ? "r" : "right";
  out.append(left, poser ? 1 : 4, std::string::npos);
  return out;
}

}  // namespace

std::vector<int> map_bvh_to_smpl(const Bvh& bvh, const std::string& what, std::string* convention) {
  std::map<std::string, int> by_name;
  for (size_t k = 0; k < bvh.joints.size(); ++k)
    by_name.emplace(normalise(bvh.joints[k].name), int(k));
  auto has = [&](const char* n) { return by_name.count(n) > 0; };
  std::vector<int> map(24, -1);
  std::string used;
  if (has("pelvis") || has("lefthip")) {
    used = "SMPL";
    for (int j = 0; j < 24; ++j) {
      auto it = by_name.find(normalise(kSmplNames[j]));
      if (it != by_name.end()) map[size_t(j)] = it->second;
    }
  } else {
    const bool poser = has("abdomen") || has("lthigh");
    const Convention& c = poser ? kPoser : (has("lowerback") || has("lhipjoint")) ? kCmu : kMixamo;
    used = c.name;
    for (int j = 0; j < 24; ++j) {
      const std::string n = convention_name(c, j, poser);
      if (n.empty()) continue;
      auto it = by_name.find(n);
      if (it != by_name.end()) map[size_t(j)] = it->second;
    }
  }
  if (convention) *convention = used;
  using namespace smpl_joint;
  std::string missing;
  for (int j : {kPelvis, kLeftHip, kRightHip, kLeftKnee, kRightKnee, kLeftAnkle, kRightAnkle,
                kLeftShoulder, kRightShoulder, kLeftElbow, kRightElbow})
    if (map[size_t(j)] < 0) missing += std::string(missing.empty() ? "" : ", ") + kSmplNames[j];
  if (!missing.empty()) {
    std::string names;
    for (size_t k = 0; k < bvh.joints.size() && k < 40; ++k)
      names += (k ? ", " : "") + bvh.joints[k].name;
    if (bvh.joints.size() > 40) names += ", ...";
    throw Error(what + ": cannot map the BVH skeleton onto the body (read as " + used +
                " names): no joint for " + missing + " (the file's joints: " + names + ")");
  }
  return map;
}

Motion bvh_to_motion(const Bvh& bvh, const std::string& name, const std::vector<int>& parents,
                     const Eigen::MatrixXd& rest, int max_frames, const std::string& what) {
  using namespace smpl_joint;
  if (parents.size() != 24 || rest.rows() != 24 || rest.cols() != 3)
    throw Error(what + ": the body skeleton must be SMPL's 24 joints");
  std::string convention;
  const std::vector<int> map = map_bvh_to_smpl(bvh, what, &convention);
  // SMPL-named files hold SMPL poses: their rest is SMPL's T-pose whatever body shape their
  // offsets come from, so they get no rest correction.
  const bool smpl_poses = convention == "SMPL";
  const Eigen::MatrixXd P = bvh.rest_positions();
  auto bpos = [&](int j) -> Eigen::Vector3d { return P.row(map[size_t(j)]).transpose(); };
  auto body = [&](int j) -> Eigen::Vector3d { return rest.row(j).transpose(); };
  // Rest corrections. The root: the frame of (left-right, up) axes of each skeleton.
  auto frame = [](Eigen::Vector3d lateral, Eigen::Vector3d up) {
    Eigen::Matrix3d F;
    const Eigen::Vector3d e1 = lateral.normalized();
    const Eigen::Vector3d e2 = (up - up.dot(e1) * e1).normalized();
    F << e1, e2, e1.cross(e2);
    return F;
  };
  int top = kPelvis;
  for (int j : {kNeck, kSpine3, kSpine2, kSpine1})
    if (map[size_t(j)] >= 0) {
      top = j;
      break;
    }
  Eigen::Vector3d up_body = body(top) - body(kPelvis), up_bvh = Eigen::Vector3d::Zero();
  if (top != kPelvis) up_bvh = bpos(top) - bpos(kPelvis);
  if (up_bvh.norm() < 1e-9) up_body = up_bvh = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d lat_body = body(kLeftHip) - body(kRightHip),
                        lat_bvh = bpos(kLeftHip) - bpos(kRightHip);
  std::vector<Eigen::Matrix3d> Q(24, Eigen::Matrix3d::Identity());
  if (!smpl_poses && lat_bvh.norm() > 1e-9 && lat_bvh.cross(up_bvh).norm() > 1e-9)
    Q[0] = frame(lat_bvh, up_bvh) * frame(lat_body, up_body).transpose();
  for (int j = 1; j < 24 && !smpl_poses; ++j) {
    const int p = parents[size_t(j)];
    Q[size_t(j)] = Q[size_t(p)];
    const int c = first_child(parents, j);
    if (c < 0 || map[size_t(j)] < 0 || map[size_t(c)] < 0) continue;
    const Eigen::Vector3d db = Q[size_t(p)] * (body(c) - body(j)), dv = bpos(c) - bpos(j);
    if (db.norm() < 1e-9 || dv.norm() < 1e-9) continue;
    Q[size_t(j)] = Eigen::Quaterniond::FromTwoVectors(db, dv).toRotationMatrix() * Q[size_t(p)];
  }
  // Root motion scale: the legs' lengths.
  auto leg = [](const Eigen::Vector3d& h, const Eigen::Vector3d& k, const Eigen::Vector3d& a) {
    return (k - h).norm() + (a - k).norm();
  };
  const double leg_bvh = leg(bpos(kLeftHip), bpos(kLeftKnee), bpos(kLeftAnkle));
  double scale =
      leg_bvh > 1e-9 ? leg(body(kLeftHip), body(kLeftKnee), body(kLeftAnkle)) / leg_bvh : 1.0;
  // SMPL poses come with their translation in metres (as AMASS's): kept unscaled unless the
  // file's legs say it is in other units.
  if (smpl_poses && scale > 0.5 && scale < 2) scale = 1;
  // Frames (subsampled to about 30 fps).
  double fps = 1.0 / bvh.frame_time;
  if (std::abs(fps - std::round(fps)) < 1e-4 * fps) fps = std::round(fps);  // 0.0333333 s: 30 fps
  int step = 1;
  if (fps > 45) step = std::max(1, int(std::lround(fps / 30.0)));
  fps /= step;
  Motion m;
  m.name = name;
  m.fps = fps;
  const int nb = int(bvh.joints.size());
  std::vector<Eigen::Matrix3d> G(static_cast<size_t>(nb));
  std::vector<Eigen::Vector3d> X(static_cast<size_t>(nb));
  Eigen::Vector3d pelvis0 = Eigen::Vector3d::Zero();
  for (long f = 0; f < bvh.frames.rows(); f += step) {
    if (max_frames > 0 && int(m.frames.size()) >= max_frames) break;
    for (int k = 0; k < nb; ++k) {
      const int p = bvh.joints[size_t(k)].parent;
      const Eigen::Matrix3d L = bvh.local_rotation(k, int(f));
      const Eigen::Vector3d t = bvh.local_translation(k, int(f));
      G[size_t(k)] = p < 0 ? L : Eigen::Matrix3d(G[size_t(p)] * L);
      X[size_t(k)] = p < 0 ? t : Eigen::Vector3d(X[size_t(p)] + G[size_t(p)] * t);
    }
    std::vector<Eigen::Matrix3d> R(24);
    BodyParams bp;
    bp.body_pose = Eigen::VectorXd::Zero(69);
    for (int j = 0; j < 24; ++j) {
      const int p = parents[size_t(j)];
      if (map[size_t(j)] >= 0)
        R[size_t(j)] = G[size_t(map[size_t(j)])] * Q[size_t(j)];
      else
        R[size_t(j)] = R[size_t(p)] * Q[size_t(p)].transpose() * Q[size_t(j)];
      const Eigen::Matrix3d local =
          p < 0 ? R[size_t(j)] : Eigen::Matrix3d(R[size_t(p)].transpose() * R[size_t(j)]);
      const Eigen::Vector3d aa = matrix_to_axis_angle(local);
      if (j == 0)
        bp.global_orient = aa;
      else
        bp.body_pose.segment<3>(3 * (j - 1)) = aa;
    }
    const Eigen::Vector3d pel = X[size_t(map[0])];
    if (m.frames.empty()) pelvis0 = pel;
    bp.transl = scale * (pel - pelvis0);
    m.frames.push_back(bp);
  }
  if (m.frames.empty()) throw Error(what + ": the BVH has no frames");
  return m;
}

Motion load_bvh_motion(const std::string& path, int frames) {
  const Bvh bvh = read_bvh(path);
  const BodyModel& model = default_body_model();
  const Eigen::MatrixXd rest = model.J_regressor * model.v_template;  // the mean shape's joints
  return bvh_to_motion(bvh, std::filesystem::path(path).stem().string(), model.parents, rest,
                       frames, path);
}

Bvh poses_to_bvh(const std::vector<int>& parents, const std::vector<std::string>& names,
                 const Eigen::MatrixXd& rest, const std::vector<Eigen::MatrixXd>& poses,
                 const std::vector<Eigen::Vector3d>& transl, double fps) {
  const int J = int(parents.size());
  if (J == 0 || rest.rows() != J || names.size() != size_t(J) || poses.size() != transl.size() ||
      poses.empty() || !(fps > 0))
    throw Error("bvh: inconsistent skeleton, poses or frame rate to write");
  // Depth-first order (BVH's), joint j -> its place.
  std::vector<int> order;
  std::vector<int> stack = {0};
  while (!stack.empty()) {
    const int j = stack.back();
    stack.pop_back();
    order.push_back(j);
    for (int c = J - 1; c >= 1; --c)
      if (parents[size_t(c)] == j) stack.push_back(c);
  }
  if (int(order.size()) != J) throw Error("bvh: the skeleton has more than one root");
  std::vector<int> place(static_cast<size_t>(J));
  for (int k = 0; k < J; ++k) place[size_t(order[size_t(k)])] = k;
  Bvh b;
  b.frame_time = 1.0 / fps;
  int channel = 0;
  for (int j : order) {
    BvhJoint bj;
    bj.name = names[size_t(j)];
    const int p = parents[size_t(j)];
    bj.parent = p < 0 ? -1 : place[size_t(p)];
    if (p >= 0) bj.offset = (rest.row(j) - rest.row(p)).transpose();
    if (p < 0) bj.channels = {BvhChannel::kXpos, BvhChannel::kYpos, BvhChannel::kZpos};
    for (BvhChannel c : {BvhChannel::kZrot, BvhChannel::kYrot, BvhChannel::kXrot})
      bj.channels.push_back(c);
    bj.first_channel = channel;
    channel += int(bj.channels.size());
    if (first_child(parents, j) < 0) {
      bj.has_end_site = true;
      bj.end_site = 0.5 * bj.offset;
      if (bj.end_site.norm() < 1e-9) bj.end_site = Eigen::Vector3d(0, 0.05, 0);
    }
    b.joints.push_back(bj);
  }
  const int F = int(poses.size());
  b.frames.resize(F, channel);
  for (int f = 0; f < F; ++f) {
    if (poses[size_t(f)].rows() != J || poses[size_t(f)].cols() != 3)
      throw Error("bvh: a pose is not J x 3");
    for (int k = 0; k < J; ++k) {
      const int j = order[size_t(k)];
      const BvhJoint& bj = b.joints[size_t(k)];
      int c = bj.first_channel;
      if (bj.parent < 0)
        for (int d = 0; d < 3; ++d) b.frames(f, c++) = rest(j, d) + transl[size_t(f)][d];
      const Eigen::Matrix3d R = axis_angle_to_matrix<double>(poses[size_t(f)].row(j).transpose());
      // R = Rz(a) Ry(b) Rx(c).
      double a, bb, cc;
      const double s = std::clamp(-R(2, 0), -1.0, 1.0);
      bb = std::asin(s);
      if (std::abs(s) < 1 - 1e-12) {
        a = std::atan2(R(1, 0), R(0, 0));
        cc = std::atan2(R(2, 1), R(2, 2));
      } else {
        a = 0;
        cc = std::atan2(s * R(0, 1), s * R(0, 2));
      }
      b.frames(f, c++) = a * 180 / kPi;
      b.frames(f, c++) = bb * 180 / kPi;
      b.frames(f, c++) = cc * 180 / kPi;
    }
  }
  return b;
}

}  // namespace ks
