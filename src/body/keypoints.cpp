#include "body/keypoints.hpp"

#include <cmath>
#include <limits>

#include "core/error.hpp"
#include "core/names.hpp"

namespace ks {

const std::array<const char*, kBody25Count>& body25_names() {
  static const std::array<const char*, kBody25Count> names = {
      "Nose",   "Neck",    "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow",
      "LWrist", "MidHip",  "RHip",      "RKnee",  "RAnkle", "LHip",      "LKnee",
      "LAnkle", "REye",    "LEye",      "REar",   "LEar",   "LBigToe",   "LSmallToe",
      "LHeel",  "RBigToe", "RSmallToe", "RHeel"};
  return names;
}

int body25_mirror(int k) {
  using namespace body25;
  static const int kMirror[kBody25Count] = {
      kNose, kNeck,    kLShoulder, kLElbow, kLWrist,  kRShoulder, kRElbow, kRWrist, kMidHip,
      kLHip, kLKnee,   kLAnkle,    kRHip,   kRKnee,   kRAnkle,    kLEye,   kREye,   kLEar,
      kREar, kRBigToe, kRSmallToe, kRHeel,  kLBigToe, kLSmallToe, kLHeel};
  return (k >= 0 && k < kBody25Count) ? kMirror[k] : k;
}

namespace {

// COCO's keypoints relative to the body's joints (metres, in the rest frame of the bone ending at
// the joint; left side; the right side mirrored in x). Measured by scripts/calibrate_keypoints.sh
// (`kinesplat calibrate-keypoints`, fit/keypoint_calibration.hpp): MoveNet on 15 synth photos
// (seeds 100-115 but 111: 8 standing, 7 in other poses and views; none of the seeds the fit is
// measured on), least squares against the true bodies, one offset for left and right.
struct CocoOffset {
  int k;
  double x, y, z;
};
constexpr CocoOffset kCocoOffsets[] = {
    {body25::kNeck, 0.0, -0.0280, 0.0137},      {body25::kLShoulder, 0.0024, 0.0431, 0.0260},
    {body25::kLElbow, 0.0215, 0.0086, -0.0125}, {body25::kLWrist, 0.0485, -0.0018, -0.0001},
    {body25::kMidHip, 0.0, 0.0163, 0.0166},     {body25::kLHip, 0.0290, 0.0163, 0.0169},
    {body25::kLKnee, 0.0087, 0.0174, 0.0329},   {body25::kLAnkle, 0.0050, 0.0196, -0.0010},
};

}  // namespace

std::array<Body25Source, kBody25Count> body25_sources(const BodyModel& model,
                                                      KeypointConvention convention) {
  using namespace body25;
  if (model.num_joints() < 22) throw Error("body keypoints: the model has fewer than 22 joints");
  std::array<Body25Source, kBody25Count> src{};
  // SMPL joint indices (the first 22 are shared by SMPL, SMPL-H, SMPL-X and the default).
  const int joint_of[kBody25Count] = {-1, 12, 17, 19, 21, 16, 18, 20, 1,  2,  5,  8, 1,
                                      4,  7,  -1, -1, -1, -1, -1, -1, -1, -1, -1, -1};
  for (int k = 0; k < kBody25Count; ++k) src[size_t(k)].joint = joint_of[k];
  src[kMidHip].joint2 = 2;  // MidHip = mean of the hips

  // Rest template, joints regressed from it.
  const Eigen::MatrixXd& V = model.v_template;
  const Eigen::MatrixXd J = model.J_regressor * V;
  const long N = V.rows();
  const bool labelled = model.part_labels.size() == size_t(N);
  const double neck_y = J(12, 1), head_x = J(15, 0);
  auto on_head = [&](long i) {
    return V(i, 1) > neck_y && (!labelled || model.part_labels[size_t(i)] == kHeadNeck);
  };
  double crown = -1e9;
  for (long i = 0; i < N; ++i)
    if (on_head(i)) crown = std::max(crown, V(i, 1));
  if (crown <= neck_y + 0.05)
    throw Error("body keypoints: the model has no head vertices above the neck");
  // Head size relative to an average adult (neck joint to crown about 0.275 m).
  const double s = std::clamp((crown - neck_y) / 0.275, 0.6, 1.6);
  auto best_vertex = [&](auto score) {
    long bi = -1;
    double bs = -std::numeric_limits<double>::infinity();
    for (long i = 0; i < N; ++i) {
      const double sc = score(i);
      if (sc > bs) {
        bs = sc;
        bi = i;
      }
    }
    return int(bi);
  };
  // Nose: the front-most head vertex near the midline, above the chin.
  src[kNose].joint = -1;
  src[kNose].vertex = best_vertex([&](long i) {
    return on_head(i) && V(i, 1) > neck_y + 0.05 * s && std::abs(V(i, 0) - head_x) < 0.012 * s
               ? V(i, 2)
               : -1e9;
  });
  const Eigen::Vector3d nose = V.row(src[kNose].vertex).transpose();
  // Eyes: front-facing head vertices about 3 cm to each side of the nose and 2-3 cm above its
  // tip; ears: the widest head vertex at eye height on each side.
  const double eye_y = nose.y() + 0.025 * s, eye_dx = 0.032 * s;
  for (int e = 0; e < 2; ++e) {  // 0: right eye/ear (-x), 1: left (+x)
    const double side = e == 0 ? -1.0 : 1.0;
    const double ex = head_x + side * eye_dx;
    const int kEye = e == 0 ? kREye : kLEye, kEar = e == 0 ? kREar : kLEar;
    src[size_t(kEye)].joint = -1;
    src[size_t(kEye)].vertex = best_vertex([&](long i) {
      if (!on_head(i) || V(i, 2) < nose.z() - 0.05 * s) return -1e9;
      return -std::hypot(V(i, 0) - ex, V(i, 1) - eye_y) + 0.2 * V(i, 2);
    });
    src[size_t(kEar)].joint = -1;
    src[size_t(kEar)].vertex = best_vertex([&](long i) {
      if (!on_head(i) || std::abs(V(i, 1) - (eye_y - 0.015 * s)) > 0.02 * s) return -1e9;
      return side * (V(i, 0) - head_x);
    });
  }
  // Feet: below the ankle on each side; big toe = front-most towards the midline, small toe =
  // front-most outward, heel = back-most low.
  for (int side = 0; side < 2; ++side) {  // 0: left (+x), 1: right (-x)
    const int ankle = side == 0 ? 7 : 8;
    const double sx = side == 0 ? 1.0 : -1.0;
    const Eigen::Vector3d a = J.row(ankle).transpose();
    auto foot = [&](long i) {
      return sx * V(i, 0) > 0 && std::abs(V(i, 0) - a.x()) < 0.09 && V(i, 1) < a.y() - 0.01;
    };
    double xc = 0;
    int cnt = 0;
    for (long i = 0; i < N; ++i)
      if (foot(i)) {
        xc += V(i, 0);
        ++cnt;
      }
    if (cnt == 0) throw Error("body keypoints: could not find the feet of the body model");
    xc /= cnt;
    const size_t base = side == 0 ? kLBigToe : kRBigToe;
    for (size_t k = base; k < base + 3; ++k) src[k].joint = -1;
    src[base].vertex =
        best_vertex([&](long i) { return foot(i) ? V(i, 2) - 0.6 * sx * (V(i, 0) - xc) : -1e9; });
    src[base + 1].vertex =
        best_vertex([&](long i) { return foot(i) ? V(i, 2) + 0.6 * sx * (V(i, 0) - xc) : -1e9; });
    src[base + 2].vertex =
        best_vertex([&](long i) { return foot(i) ? -V(i, 2) - 0.5 * V(i, 1) : -1e9; });
  }
  for (int k = 0; k < kBody25Count; ++k) {
    Body25Source& b = src[size_t(k)];
    if (b.vertex >= 0) continue;
    b.frame = b.joint2 >= 0 ? 0 : std::max(0, model.parents[size_t(b.joint)]);
  }
  if (convention == KeypointConvention::kCoco)
    for (const CocoOffset& c : kCocoOffsets) {
      src[size_t(c.k)].offset = Eigen::Vector3d(c.x, c.y, c.z);
      const int m = body25_mirror(c.k);
      if (m != c.k) src[size_t(m)].offset = Eigen::Vector3d(-c.x, c.y, c.z);
    }
  return src;
}

Eigen::MatrixXd body25_points(const std::array<Body25Source, kBody25Count>& sources,
                              const Eigen::MatrixXd& joints, const Eigen::MatrixXd& vertices,
                              const std::vector<Eigen::Matrix4d>* transforms) {
  Eigen::MatrixXd P(kBody25Count, 3);
  for (int k = 0; k < kBody25Count; ++k) {
    const Body25Source& s = sources[size_t(k)];
    if (s.vertex >= 0) {
      P.row(k) = vertices.row(s.vertex);
    } else {
      P.row(k) = joints.row(s.joint);
      if (s.joint2 >= 0) P.row(k) = 0.5 * (P.row(k) + joints.row(s.joint2));
      if (transforms && s.frame >= 0 && !s.offset.isZero(0))
        P.row(k) += ((*transforms)[size_t(s.frame)].topLeftCorner<3, 3>() * s.offset).transpose();
    }
  }
  return P;
}

const std::vector<std::string>& keypoint_convention_names() {
  static const std::vector<std::string> n = {"joints", "coco"};
  return n;
}

const char* to_string(KeypointConvention c) {
  return keypoint_convention_names()[size_t(c)].c_str();
}

KeypointConvention parse_keypoint_convention(const std::string& name) {
  return parse_name<KeypointConvention>(keypoint_convention_names(), name, "keypoint convention");
}

}  // namespace ks
