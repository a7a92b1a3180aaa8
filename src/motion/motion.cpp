#include "motion/motion.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>

#include "core/error.hpp"
#include "core/math.hpp"
#include "core/rotation.hpp"
#include "motion/amass.hpp"
#include "motion/bvh_motion.hpp"

namespace ks {

namespace {

using namespace smpl_joint;

constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d rx(double deg) {
  return Eigen::AngleAxisd(deg * kDeg, Eigen::Vector3d::UnitX()).toRotationMatrix();
}
Eigen::Matrix3d ry(double deg) {
  return Eigen::AngleAxisd(deg * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
}
Eigen::Matrix3d rz(double deg) {
  return Eigen::AngleAxisd(deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

Eigen::Vector3d to_aa(const Eigen::Matrix3d& R) {
  return matrix_to_axis_angle(R);
}

// A pose under construction: rotations per joint (1..23), composed in the parent frame.
struct Pose {
  Eigen::Matrix3d R[24];
  Eigen::Vector3d transl = Eigen::Vector3d::Zero();
  // Rotation about world Y applied on top of R[0]; with R[0] = I the global orientation is
  // written as (0, yaw, 0) exactly, so a 360 degree turn is a continuous axis-angle vector.
  double yaw_deg = 0.0;
  Pose() {
    for (auto& r : R) r.setIdentity();
  }
  // Applies `Q` after the joint's current rotation (in the parent's frame).
  void pre(int joint, const Eigen::Matrix3d& Q) { R[joint] = Q * R[joint]; }
  BodyParams params() const {
    BodyParams p;
    if (R[0].isIdentity(0))
      p.global_orient = Eigen::Vector3d(0.0, yaw_deg * kDeg, 0.0);
    else
      p.global_orient = to_aa(ry(yaw_deg) * R[0]);
    p.body_pose = Eigen::VectorXd::Zero(69);
    for (int j = 1; j < 24; ++j) p.body_pose.segment<3>(3 * (j - 1)) = to_aa(R[j]);
    p.transl = transl;
    return p;
  }
};

// Arms lowered to an A-pose (left arm along +X rotates by -angle about Z, right by +angle),
// with a little of the lowering in the collar bones; elbows bent forward a little.
void stance(Pose& p, double arm_down, double elbow = 12.0) {
  const double collar = std::min(arm_down, 8.0) * (arm_down >= 0 ? 1.0 : 0.0);
  p.R[kLeftCollar] = rz(-collar);
  p.R[kRightCollar] = rz(collar);
  p.R[kLeftShoulder] = rz(-(arm_down - collar));
  p.R[kRightShoulder] = rz(arm_down - collar);
  // Elbow flexion (forearm forward): about the local Y axis, negative for the left arm.
  p.R[kLeftElbow] = ry(-elbow);
  p.R[kRightElbow] = ry(elbow);
}

// One leg's step: hip flexion (thigh forward: negative X), knee flexion (shin back: positive
// X), ankle.
void leg(Pose& p, bool left, double hip_flex, double knee_flex, double ankle) {
  p.R[left ? kLeftHip : kRightHip] = rx(-hip_flex);
  p.R[left ? kLeftKnee : kRightKnee] = rx(knee_flex);
  p.R[left ? kLeftAnkle : kRightAnkle] = rx(ankle);
}

// Normalised time u in [0, 1) (or [0, 1] for non-cyclic motions) -> pose.
Pose turn_pose(double u) {
  Pose p;
  const double phase = 2 * M_PI * 4 * u;  // 4 step cycles (8 small steps) per turn
  const double s = std::sin(phase);
  // The arms rise by 30 degrees four times per turn, highest at the diagonal views (between
  // steps), so that the sides of the torso, the armpits and the undersides of the arms are seen
  // from the fixed camera; at the front, side and back views they hang in the A-pose.
  const double raise = 30.0;
  const double up = 0.5 - 0.5 * std::cos(phase);
  stance(p, 62.0 - raise * up, 14.0 + 4.0 * (0.5 - 0.5 * std::cos(phase)));
  const double lift_l = std::pow(std::max(0.0, s), 2), lift_r = std::pow(std::max(0.0, -s), 2);
  leg(p, true, 14.0 * lift_l, 28.0 * lift_l, -8.0 * lift_l);
  leg(p, false, 14.0 * lift_r, 28.0 * lift_r, -8.0 * lift_r);
  // Arm swing opposite to the legs (rotation about X: positive swings the arm backwards).
  p.pre(kLeftShoulder, rx(7.0 * s));
  p.pre(kRightShoulder, rx(-7.0 * s));
  // A slight lean of the upper body into the turn and a head that leads it.
  p.R[kSpine2] = ry(3.0);
  p.R[kHead] = ry(4.0) * rx(3.0);
  p.yaw_deg = 360.0 * u;
  return p;
}

Pose walk_pose(double u) {
  Pose p;
  const double cycles = 2.0;
  const double phase = 2 * M_PI * cycles * u;
  const double s = std::sin(phase);
  stance(p, 70.0, 18.0);
  // Left leg swings forward while phase in (-pi/2, pi/2); knee flexes most in mid-swing.
  auto knee = [](double ph) {
    const double sw = std::max(0.0, std::cos(ph));
    return 6.0 + 50.0 * sw * sw;
  };
  leg(p, true, 24.0 * s, knee(phase), -6.0 * s);
  leg(p, false, -24.0 * s, knee(phase + M_PI), 6.0 * s);
  // Arms swing opposite to the legs.
  p.pre(kLeftShoulder, rx(18.0 * s));
  p.pre(kRightShoulder, rx(-18.0 * s));
  p.R[kLeftElbow] = ry(-(18.0 + 10.0 * std::max(0.0, -s)));
  p.R[kRightElbow] = ry(18.0 + 10.0 * std::max(0.0, s));
  // Pelvis and torso counter-rotation, vertical bob twice per cycle, forward travel.
  p.R[0] = ry(-5.0 * s);
  p.R[kSpine2] = ry(8.0 * s);
  p.R[kSpine1] = rx(4.0);
  const double stride = 1.3;  // metres per cycle (two steps)
  p.transl = Eigen::Vector3d(0.0, 0.015 * std::cos(2 * phase), stride * cycles * u);
  return p;
}

Pose wave_pose(double u) {
  Pose p;
  stance(p, 62.0, 12.0);
  // Right arm: raise (0.0 - 0.25), wave (0.25 - 0.8), lower (0.8 - 1.0).
  const double up = smoothstep(0.0, 0.25, u) * (1.0 - smoothstep(0.8, 1.0, u));
  const double wave_phase = 2 * M_PI * 3.0 * std::clamp((u - 0.25) / 0.55, 0.0, 1.0);
  const double wave =
      std::sin(wave_phase) * smoothstep(0.2, 0.3, u) * (1 - smoothstep(0.75, 0.85, u));
  // Upper arm from 62 degrees down to 20 degrees above the horizontal, a little forward;
  // forearm raised to vertical and swung side to side about the elbow.
  const double shoulder = 54.0 + (-20.0 - 54.0) * up;
  p.R[kRightCollar] = rz(8.0 * (1 - up));
  p.R[kRightShoulder] = ry(20.0 * up) * rz(shoulder);
  p.R[kRightElbow] = rz(-70.0 * up + 22.0 * wave) * ry(12.0 * (1 - up));
  p.R[kRightWrist] = rz(10.0 * wave);
  p.R[kHead] = rz(-5.0 * up) * rx(-3.0 * up);
  p.R[kSpine2] = rz(2.0 * up);
  return p;
}

Pose dance_pose(double u) {
  Pose p;
  const double beats = 3.0;
  const double phase = 2 * M_PI * beats * u;
  const double s = std::sin(phase);
  const double bounce = 0.5 - 0.5 * std::cos(2 * phase);  // two bounces per beat
  // Arms pump in turn: left up while right down.
  const double left_up = 0.5 + 0.5 * s, right_up = 0.5 - 0.5 * s;
  p.R[kLeftShoulder] = rz(-60.0 + 95.0 * left_up) * ry(-15.0);
  p.R[kRightShoulder] = rz(60.0 - 95.0 * right_up) * ry(15.0);
  p.R[kLeftElbow] = ry(-(25.0 + 40.0 * left_up));
  p.R[kRightElbow] = ry(25.0 + 40.0 * right_up);
  // Knees bounce, hips sway, torso twists, head nods.
  const double k = 8.0 + 16.0 * bounce;
  leg(p, true, 0.5 * k + 6.0 * std::max(0.0, s), k, -0.5 * k);
  leg(p, false, 0.5 * k + 6.0 * std::max(0.0, -s), k, -0.5 * k);
  p.R[kLeftHip] = rz(6.0) * p.R[kLeftHip];
  p.R[kRightHip] = rz(-6.0) * p.R[kRightHip];
  p.R[kSpine1] = rz(-4.0 * s);
  p.R[kSpine2] = ry(14.0 * s);
  p.R[kHead] = rx(7.0 * std::sin(2 * phase)) * ry(-6.0 * s);
  p.R[0] = ry(10.0 * std::sin(phase * 0.5));
  p.transl = Eigen::Vector3d(0.05 * s, -0.03 * bounce, 0.0);
  return p;
}

Pose a_t_pose(double u) {
  Pose p;
  const double down = 62.0 * (0.5 + 0.5 * std::cos(2 * M_PI * u));  // A -> T -> A
  stance(p, down, 12.0 * down / 62.0);
  return p;
}

struct Builtin {
  MotionInfo info;
  bool cyclic;  // sampled at i / N (true) or i / (N - 1) (false)
  std::function<Pose(double)> pose;
};

const std::vector<Builtin>& builtins() {
  static const std::vector<Builtin> b = {
      {{"turn",
        "360 degree turn in place, arms in an A-pose with a gentle swing that rise four times "
        "(at the diagonal views), small steps "
        "(SinGS pose-space sampling)",
        64},
       true,
       turn_pose},
      {{"walk", "two walk cycles (four steps) forwards along +Z with arm swing", 64},
       true,
       walk_pose},
      {{"wave", "raise the right arm, wave three times, lower it", 90}, false, wave_pose},
      {{"dance", "short dance: knee bounce, hip sway, torso twist, arms pumping in turn", 96},
       true,
       dance_pose},
      {{"a-t-pose", "A-pose to T-pose and back", 60}, true, a_t_pose},
  };
  return b;
}

}  // namespace

const std::vector<MotionInfo>& builtin_motions() {
  static const std::vector<MotionInfo> infos = [] {
    std::vector<MotionInfo> v;
    for (const auto& b : builtins()) v.push_back(b.info);
    return v;
  }();
  return infos;
}

Motion builtin_motion(const std::string& name, int frames) {
  for (const auto& b : builtins()) {
    if (b.info.name != name) continue;
    if (frames < 0) throw Error("motion \"" + name + "\": number of frames must be positive");
    const int n = frames == 0 ? b.info.default_frames : frames;
    Motion m;
    m.name = name;
    m.fps = 30.0 * n / b.info.default_frames;
    m.frames.reserve(n);
    for (int i = 0; i < n; ++i) {
      const double u = b.cyclic ? double(i) / n : (n > 1 ? double(i) / (n - 1) : 0.0);
      m.frames.push_back(b.pose(u).params());
    }
    return m;
  }
  std::string names;
  for (const auto& b : builtins()) names += (names.empty() ? "" : ", ") + b.info.name;
  throw Error("unknown motion \"" + name + "\" (built-in motions: " + names + ")");
}

Motion load_motion(const std::string& name_or_path, int frames) {
  for (const auto& b : builtins())
    if (b.info.name == name_or_path) return builtin_motion(name_or_path, frames);
  const auto n = name_or_path.size();
  if (n > 4 && name_or_path.compare(n - 4, 4, ".npz") == 0)
    return load_amass_npz(name_or_path, frames);  // AMASS (src/motion/amass.hpp)
  if (n > 4 && name_or_path.compare(n - 4, 4, ".bvh") == 0)
    return load_bvh_motion(name_or_path, frames);  // BVH (src/motion/bvh_motion.hpp)
  throw Error("unknown motion \"" + name_or_path +
              "\": not a built-in motion (see `kinesplat motions`)");
}

BodyParams standing_pose(double arm_down_degrees) {
  Pose p;
  stance(p, arm_down_degrees, 14.0);
  return p.params();
}

void adapt_body_pose(BodyParams& params, int num_body_pose_joints) {
  const long n = 3L * num_body_pose_joints;
  Eigen::VectorXd v = Eigen::VectorXd::Zero(n);
  const long k = std::min<long>(n, params.body_pose.size());
  v.head(k) = params.body_pose.head(k);
  params.body_pose = v;
}

}  // namespace ks
