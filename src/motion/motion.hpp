#pragma once
// Motions: sequences of body poses for SMPL's 24-joint skeleton (the default model's too).
// Joint rotations are axis-angles relative to the parent joint, in the SMPL rest pose's frame
// (world: Y up, the body faces +Z, its left is +X; the rest pose is a T-pose with arms along
// +-X). Every built-in motion is a smooth function of normalised time, sampled at `frames`
// points, so any length gives the same movement (fps is scaled to keep its duration).
#include <string>
#include <vector>

#include "body/body_model.hpp"
#include "body/joints.hpp"

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
// A built-in name, or a file (AMASS .npz, BVH .bvh; see docs/formats.md).
Motion load_motion(const std::string& name_or_path, int frames = 0);

// A natural standing pose: the rest T-pose with the arms lowered `arm_down_degrees` from the
// horizontal (A-pose), elbows slightly bent, facing +Z. 69 body_pose values.
BodyParams standing_pose(double arm_down_degrees = 62.0);

// Body pose vector of a motion for a model with `num_body_pose_joints` joints driven by
// body_pose (23 for SMPL / default, 21 for SMPL-H / SMPL-X): truncates or zero-pads.
void adapt_body_pose(BodyParams& params, int num_body_pose_joints);

}  // namespace ks
