#pragma once
// Posing and rendering a frame of an avatar in one pass: the rasterizer's projection poses each
// chunk of Gaussians with the avatar's skin (body/lbs.hpp LbsRanges) as it reads it, so the posed
// Gaussians never make a round trip through memory. The same image as pose_avatar followed by
// rasterize_forward, bit for bit. What playback renders with.
#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "body/lbs.hpp"
#include "core/camera.hpp"
#include "raster/rasterizer.hpp"

namespace ks {

class PosedRenderer {
 public:
  // Checks the avatar's skin once (ks::Error); the avatar must outlive this.
  explicit PosedRenderer(const Avatar& avatar);
  // One frame: `params` (the avatar's own shape), `cull` optional (its normals must outlive the
  // call).
  void render(const BodyParams& params, const Camera& camera, const RasterSettings& settings,
              RasterResult& out, const BackfaceCull* cull = nullptr);

 private:
  const Avatar& avatar_;
  LbsRanges skin_;
  AvatarPoseInputs pose_;
};

}  // namespace ks
