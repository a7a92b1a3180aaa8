#pragma once
// BODY_25 keypoints (OpenPose's order) on a body model: each keypoint is a joint of the
// skeleton, the mean of two joints (MidHip), or a vertex of the surface (nose, eyes, ears, toes,
// heels), chosen once on the model's rest template by geometric rules. The fit projects these
// points and compares them with detected keypoints.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "body/body_model.hpp"

namespace ks {

inline constexpr int kBody25Count = 25;

namespace body25 {
enum : int {
  kNose = 0,
  kNeck = 1,
  kRShoulder = 2,
  kRElbow = 3,
  kRWrist = 4,
  kLShoulder = 5,
  kLElbow = 6,
  kLWrist = 7,
  kMidHip = 8,
  kRHip = 9,
  kRKnee = 10,
  kRAnkle = 11,
  kLHip = 12,
  kLKnee = 13,
  kLAnkle = 14,
  kREye = 15,
  kLEye = 16,
  kREar = 17,
  kLEar = 18,
  kLBigToe = 19,
  kLSmallToe = 20,
  kLHeel = 21,
  kRBigToe = 22,
  kRSmallToe = 23,
  kRHeel = 24,
};
}  // namespace body25

// OpenPose's BODY_25 names ("Nose", "Neck", ..., "RHeel").
const std::array<const char*, kBody25Count>& body25_names();

// The keypoint a BODY_25 index has on the image's other side of the body (left <-> right).
int body25_mirror(int k);

struct Body25Source {
  int joint = -1;   // a joint, or
  int joint2 = -1;  // with `joint`: the mean of the two joints
  int vertex = -1;  // a template vertex (joint == -1)
  // For joint keypoints: an offset (metres) in the rest frame of joint `frame` (the bone that
  // ends at `joint`: its parent; the pelvis for MidHip), turned with that joint.
  int frame = -1;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};

// What a keypoint file's points mark. kJoints: the body model's joints (the synth's
// photo_keypoints.json). kCoco: where COCO's annotators (and so every detector trained on COCO:
// MoveNet, OpenPose, DWPose) put them: shoulders on top of the shoulder, hips at their sides,
// wrists further down the arm, knees at the kneecap; the offsets from the joints were measured
// (docs/fit.md, "Keypoint conventions").
enum class KeypointConvention { kJoints, kCoco };

// "joints" / "coco", and back (ks::Error naming the value for any other name).
const char* to_string(KeypointConvention c);
KeypointConvention parse_keypoint_convention(const std::string& name);
// Every convention's name, in the enum's order.
const std::vector<std::string>& keypoint_convention_names();

// The sources of the 25 keypoints on `model` (SMPL, SMPL-H, SMPL-X or the default: the first 22
// joints are SMPL's). Throws ks::Error if the model has no head above the neck or no feet.
std::array<Body25Source, kBody25Count> body25_sources(
    const BodyModel& model, KeypointConvention convention = KeypointConvention::kJoints);

// The 25 points (25 x 3) of a posed body from its joints (J x 3) and vertices (V x 3); offsets
// (kCoco) need the skinning transforms (BodyState::transforms), without them they are left out.
Eigen::MatrixXd body25_points(const std::array<Body25Source, kBody25Count>& sources,
                              const Eigen::MatrixXd& joints, const Eigen::MatrixXd& vertices,
                              const std::vector<Eigen::Matrix4d>* transforms = nullptr);

}  // namespace ks
