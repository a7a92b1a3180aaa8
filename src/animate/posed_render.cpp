#include "animate/posed_render.hpp"

namespace ks {

namespace {

// The rasterizer's view of the skin: each chunk posed as the projection asks for it.
class SkinSource : public GaussianSource {
 public:
  explicit SkinSource(const LbsRanges& skin) : skin_(skin) {}
  void fill(size_t b, size_t e, float* means, float* quats, float* opacity_logits) const override {
    skin_.pose(b, e, means, quats, opacity_logits);
  }

 private:
  const LbsRanges& skin_;
};

}  // namespace

PosedRenderer::PosedRenderer(const Avatar& avatar)
    : avatar_(avatar),
      skin_(avatar.gaussians, avatar.skin_joints, avatar.skin_weights, avatar.num_joints()) {}

void PosedRenderer::render(const BodyParams& params, const Camera& camera,
                           const RasterSettings& settings, RasterResult& out,
                           const BackfaceCull* cull) {
  pose_ = avatar_pose_inputs(avatar_, params);
  skin_.set_pose(pose_.transforms, pose_.offsets.size() > 0 ? pose_.offsets.data() : nullptr, cull);
  rasterize_forward(avatar_.gaussians, SkinSource(skin_), camera, settings, out);
}

}  // namespace ks
