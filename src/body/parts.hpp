#pragma once
// SinGS's 15 semantic body parts.
#include <array>
#include <string_view>

namespace ks {

enum Part : int {
  kHeadNeck = 0,
  kTorso = 1,
  kHips = 2,
  kLeftUpperArm = 3,
  kRightUpperArm = 4,
  kLeftLowerArm = 5,
  kRightLowerArm = 6,
  kLeftHand = 7,
  kRightHand = 8,
  kLeftUpperLeg = 9,
  kRightUpperLeg = 10,
  kLeftLowerLeg = 11,
  kRightLowerLeg = 12,
  kLeftFoot = 13,
  kRightFoot = 14,
  kNumParts = 15
};

inline constexpr std::array<std::string_view, kNumParts> kPartNames = {
    "head_neck",       "torso",           "hips",
    "left_upper_arm",  "right_upper_arm", "left_lower_arm",
    "right_lower_arm", "left_hand",       "right_hand",
    "left_upper_leg",  "right_upper_leg", "left_lower_leg",
    "right_lower_leg", "left_foot",       "right_foot"};

}  // namespace ks
