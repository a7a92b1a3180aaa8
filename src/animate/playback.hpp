#pragma once
// Playback: an avatar posed along a motion and rendered frame by frame, written as PNG frames
// (a folder), an MP4 (io/video.hpp) and optionally one 3DGS .ply per frame. What `kinesplat
// animate` and `create` run.
#include <string>

#include "avatar/avatar.hpp"

namespace ks {

struct PlaybackOptions {
  std::string motion = "turn";   // a built-in name (`kinesplat motions`) or an AMASS .npz
  std::string camera = "front";  // front | orbit | camera JSON (animate/framing.hpp)
  int width = 512, height = 768;
  int frames = 0;    // 0: the motion's length
  bool ply = false;  // also a .ply per frame (turns back-face culling off)
  // Skip Gaussians whose posed normal faces away from the camera by more than this cosine (1: off).
  float backface_cull = 1.f;
  float background[3] = {1.f, 1.f, 1.f};
  // Pose and rasterize on an NVIDIA GPU (raster_cuda/; a build with KS_CUDA): the canonical
  // Gaussians and their skin uploaded once; each frame the skeleton's transforms computed on the
  // CPU (avatar_pose_inputs) and uploaded, the Gaussians skinned on the device
  // (RasterizerCuda::pose), the image downloaded.
  bool cuda = false;
  bool progress = true;
};

struct PlaybackReport {
  int frames = 0;
  double fps = 0;               // the motion's
  double render_ms = 0;         // pose + render per frame (mean)
  double render_median_ms = 0;  // ... the median frame's
  double render_max_ms = 0;     // ... the slowest frame's (the first, which sizes the buffers,
                                // as a rule)
  bool culled = false;
  std::string frames_dir;  // where the PNG (and .ply) frames are; empty when only the MP4 is kept
};

// `out`: a folder (PNG frames) or FILE.mp4 (the frames are staged beside it and removed unless
// `ply`). Outputs appear whole or not at all. Throws ks::Error for bad options, an unknown motion
// or a missing ffmpeg (before rendering anything).
PlaybackReport render_playback(const Avatar& avatar, const std::string& out,
                               const PlaybackOptions& options = {});

}  // namespace ks
