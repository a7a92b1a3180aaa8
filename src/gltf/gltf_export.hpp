#pragma once
// `kinesplat export AVATAR --gltf OUT.glb`: an avatar as one glTF 2.0 binary file (docs/export.md).
//   nodes 0..J-1   the skeleton, node j = joint j (the body's joint names), translation = its rest
//                  offset from its parent (the root's: its rest position), rotation = identity
//   skin 0         joints = nodes 0..J-1, inverse bind matrices = translation by -rest_j, so the
//                  glTF joint matrix of joint j is exactly kinesplat's skinning transform A_j
//   mesh "avatar_mesh" (mesh): the avatar's canonical template surface at rest (TRIANGLES),
//                  NORMAL, COLOR_0 (linear RGB: the band-0 colour of the Gaussians anchored at
//                  each vertex, sRGB-decoded), JOINTS_0 / WEIGHTS_0 (top 4 of those Gaussians'
//                  skin weights, normalised)
//   mesh "avatar_splats" (splats): the canonical Gaussians as a POINTS primitive with the
//                  KHR_gaussian_splatting attributes (ROTATION unit xyzw, linear SCALE,
//                  post-sigmoid OPACITY, SH_DEGREE_l_COEF_n), COLOR_0 (linear RGBA fallback) and
//                  the avatar's own top-4 JOINTS_0 / WEIGHTS_0 under the same skin
//   animations     one per motion: a rotation channel per joint (the joint's local rotation,
//                  unit xyzw) and the root's translation (rest position + transl), LINEAR, keyed
//                  at the motion's frames (t = frame / fps)
// World: metres, Y up, the body facing +Z: glTF's own frame, so nothing is converted. Pose
// correctives (SMPL-family avatars' posedirs) are not exported: engines skin with LBS only.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "avatar/avatar.hpp"
#include "motion/motion.hpp"

namespace ks {

struct GltfExportOptions {
  bool mesh = true;    // the skinned template surface with vertex colours
  bool splats = true;  // the KHR_gaussian_splatting POINTS primitive
};

// Per template vertex: its colour and skin weights baked from the Gaussians. Each Gaussian is
// assigned to the template vertex nearest its anchor; a vertex takes the opacity-weighted mean of
// its Gaussians' band-0 colours (SH dc * sh::kC0 + 0.5, clamped to [0, 1]; display sRGB) and their
// opacity-weighted skin weights reduced to the top 4 (body/skin_weights.hpp); a vertex no
// Gaussian is assigned to takes the Gaussian whose anchor is nearest.
struct BakedVertexAttributes {
  std::vector<float> srgb;      // 3 V
  std::vector<int32_t> joints;  // 4 V
  std::vector<float> weights;   // 4 V
};
BakedVertexAttributes bake_vertex_attributes(const Avatar& avatar);

// The GLB bytes. Throws ks::Error for an avatar without Gaussians (splats) or without a template
// surface (mesh), neither part chosen, more than 65536 joints, or an empty motion.
std::vector<uint8_t> avatar_gltf(const Avatar& avatar, const std::vector<Motion>& motions,
                                 const GltfExportOptions& opt = {});
// Writes avatar_gltf atomically.
void export_gltf(const std::string& path, const Avatar& avatar, const std::vector<Motion>& motions,
                 const GltfExportOptions& opt = {});

// sRGB transfer function decoded (display sRGB in [0, 1] -> linear), as glTF's COLOR_0 wants.
float srgb_to_linear(float c);

}  // namespace ks
