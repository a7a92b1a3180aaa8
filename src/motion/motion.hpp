#pragma once
// Motions: sequences of body poses for SMPL's 24-joint skeleton (the default model's too).
#include <string>
#include <vector>

#include "body/body_model.hpp"

namespace ks {

struct Motion {
  std::string name;
  double fps = 30.0;
  std::vector<BodyParams> frames;  // global_orient, body_pose (69), transl
};

struct MotionInfo {
  std::string name;
  std::string description;
  int default_frames;
};

// The built-in motions: "turn" (360 degree turn in place with natural arm and leg motion:
// SinGS's pose-space sampling), "walk", "wave", "dance", "a-t-pose".
const std::vector<MotionInfo>& builtin_motions();
// frames = 0: the motion's default length. Throws ks::Error for an unknown name.
Motion builtin_motion(const std::string& name, int frames = 0);
// A built-in name, or a file (AMASS .npz; see docs/formats.md).
Motion load_motion(const std::string& name_or_path, int frames = 0);

}  // namespace ks
