#pragma once
// `kinesplat synth`: the synthetic dataset writer (photo, keypoints, subject, train and test sets).
#include <array>
#include <cstdint>
#include <string>

#include "synth/person.hpp"

namespace ks {

// `kinesplat synth`: writes photo.png, photo_mask.png, photo_keypoints.json, subject.json,
// train/ (a motion, by default the "turn" sequence, seen by a fixed front camera or one orbiting
// the body) and test/ (8 novel poses x 4 views) into out_dir, atomically (a staging directory
// renamed into place when complete).
struct SynthRunConfig {
  uint64_t seed = 0;
  std::string out_dir;
  int width = 512;
  int height = 768;
  int frames = 64;  // of the training split: the motion sampled at this many frames
  // The training split's motion: a built-in name or a motion file (motion/motion.hpp's
  // load_motion), and its camera: "fixed" (one front camera framing the whole motion) or
  // "orbit" (once round the body over the sequence, at the fixed camera's distance).
  std::string motion = "turn";
  std::string camera = "fixed";
  bool video = false;  // train/video.mp4 too (the training frames at the motion's frame rate)
  std::string body_model = "default";
  int supersample = 2;
  // The photo's pose, "MOTION:FRAME" of a built-in motion (empty: the standing pose), and the
  // azimuth of its camera about the body (0: in front). Any other than the defaults gets a camera
  // of its own framing that pose; train/ keeps the front camera.
  std::string photo_pose;
  double photo_azimuth = 0;
  SynthOptions options;
  bool progress = true;
};
void run_synth(const SynthRunConfig& config);

// The 8 test poses of run_synth: frames of built-in motions (at their default lengths), none of
// them in the "turn" sequence.
struct SynthTestPose {
  const char* motion;
  int frame;
};
extern const std::array<SynthTestPose, 8> kSynthTestPoses;

}  // namespace ks
