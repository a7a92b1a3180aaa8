#pragma once
// SMPL's skeleton by name: the 24 joint indices (SMPL and the default model; SMPL+H and SMPL-X
// share the first 22), their parents, and lookup of a joint by name in a model's joint list.
#include <string>
#include <string_view>
#include <vector>

namespace ks {

// Indices into SMPL's 24 joints (0 = pelvis, the root; body_pose holds joints 1..23).
namespace smpl_joint {
enum : int {
  kPelvis = 0,
  kLeftHip = 1,
  kRightHip = 2,
  kSpine1 = 3,
  kLeftKnee = 4,
  kRightKnee = 5,
  kSpine2 = 6,
  kLeftAnkle = 7,
  kRightAnkle = 8,
  kSpine3 = 9,
  kLeftFoot = 10,
  kRightFoot = 11,
  kNeck = 12,
  kLeftCollar = 13,
  kRightCollar = 14,
  kHead = 15,
  kLeftShoulder = 16,
  kRightShoulder = 17,
  kLeftElbow = 18,
  kRightElbow = 19,
  kLeftWrist = 20,
  kRightWrist = 21,
  kLeftHand = 22,
  kRightHand = 23
};
}  // namespace smpl_joint

// Parents of SMPL's 24-joint skeleton (the default model's too).
const std::vector<int>& smpl_parents();

// The first child of joint j (the lowest-numbered joint whose parent is j), or -1 for a leaf.
int first_child(const std::vector<int>& parents, int j);

// The index of the joint called `name` in `names`, or -1.
int find_joint(const std::vector<std::string>& names, std::string_view name);
// The same, throwing ks::Error ("<what>: the body model has no joint named '<name>'") if absent.
int require_joint(const std::vector<std::string>& names, std::string_view name,
                  const std::string& what);

}  // namespace ks
