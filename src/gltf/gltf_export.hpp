#pragma once
// `kinesplat export AVATAR --gltf OUT.glb`: an avatar as one glTF 2.0 binary file (docs/export.md).
//   nodes 0..J-1   the skeleton, node j = joint j (the body's joint names), translation = its rest
//                  offset from its parent (the root's: its rest position), rotation = identity
//   skin 0         joints = nodes 0..J-1, inverse bind matrices = translation by -rest_j, so the
//                  glTF joint matrix of joint j is exactly kinesplat's skinning transform A_j
//   mesh "avatar_mesh" (mesh): the avatar's canonical template surface at rest (TRIANGLES),
//                  NORMAL, JOINTS_0 / WEIGHTS_0 (top 4 of the skin weights of the Gaussians at
//                  each vertex, normalised) and its colour baked from the Gaussians: a PNG
//                  base-colour texture over the project's own UV atlas (TEXCOORD_0; vertices on
//                  chart borders copied per chart) or, with vertex_colors, COLOR_0 (linear RGB);
//                  an unlit material (KHR_materials_unlit: the colours have the lighting in them)
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
#include "gltf/color_bake.hpp"
#include "motion/motion.hpp"

namespace ks {

struct GltfExportOptions {
  bool mesh = true;            // the skinned template surface
  bool splats = true;          // the KHR_gaussian_splatting POINTS primitive
  bool vertex_colors = false;  // the mesh's colour as COLOR_0 instead of a texture over a UV atlas
  bool template_surface = false;  // the template's own vertices, not the splats' (splat_surface)
  TextureBakeOptions texture;     // the atlas and the bake (gltf/color_bake.hpp)
};

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
