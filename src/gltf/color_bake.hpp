#pragma once
// The avatar's colour and skin weights baked from its Gaussians onto its template surface, for the
// glTF export's mesh (docs/export.md): per vertex (COLOR_0, JOINTS_0 / WEIGHTS_0) and into a
// texture over a UV atlas (mesh/uv_atlas.hpp).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "avatar/avatar.hpp"
#include "core/image.hpp"
#include "mesh/uv_atlas.hpp"

namespace ks {

// Each Gaussian is assigned to the template vertex nearest its anchor; per vertex, the Gaussians
// assigned to it (a vertex none is assigned to takes the Gaussian whose anchor is nearest).
std::vector<std::vector<int>> gaussians_per_vertex(const Avatar& avatar);

// A Gaussian's band-0 colour, SH dc * sh::kC0 + 0.5 clamped to [0, 1] (display sRGB).
Eigen::Vector3f band0_srgb(const Gaussians& g, size_t i);

// Per template vertex: the opacity-weighted mean of its Gaussians' band-0 colours (SH dc *
// sh::kC0 + 0.5, clamped to [0, 1]; display sRGB) and their opacity-weighted skin weights
// reduced to the top 4 (body/skin_weights.hpp).
struct BakedVertexAttributes {
  std::vector<float> srgb;      // 3 V
  std::vector<int32_t> joints;  // 4 V
  std::vector<float> weights;   // 4 V
};
// Throws ks::Error for an avatar without a template surface or Gaussians, or whose anchors or
// skin weights do not match its Gaussians.
BakedVertexAttributes bake_vertex_attributes(const Avatar& avatar,
                                             const std::vector<std::vector<int>>& members);
BakedVertexAttributes bake_vertex_attributes(const Avatar& avatar);

// The surface the splats show, per template vertex: moved to the opacity-weighted mean of its
// Gaussians' centres (their learned offsets), then out along the template's normal by the
// distance at which such a Gaussian seen edge-on falls to half coverage, r = s sqrt(2 ln(2 a))
// (s: its tangential radius, the mean of its two largest scales; a: its opacity; 0 for a <= 0.5),
// opacity-weighted likewise. Skinned with the vertex's weights it goes where the splats go.
Eigen::MatrixXd splat_surface(const Avatar& avatar, const std::vector<std::vector<int>>& members);

struct TextureBakeOptions {
  UvAtlasOptions atlas;
  // Weight of the vertex colours (interpolated over the face) beside the Gaussians' at a texel:
  // they decide only where no Gaussian reaches the surface.
  float vertex_colour_weight = 1e-3f;
};

// The colour as a texture: the atlas (laid out on the template, whose normals are smooth), and
// an RGB image (display sRGB, as glTF's baseColorTexture wants) of atlas.size x atlas.size. A
// texel on a face stands for the point of `surface` (the template's topology: the template
// itself or splat_surface) at the same barycentric coordinates; it takes the opacity- and
// density-weighted mean of the band-0 colours of the Gaussians hung on the face's vertices and
// their neighbours, each weighted by its density there with the offset along the face's normal
// removed (so a splat lifted off the surface still colours it); texels off every face take their
// neighbours' colour for `padding` + 1 rings (the gutter), the rest stay black.
struct BakedTexture {
  UvAtlas atlas;
  Image image;
};
BakedTexture bake_texture(const Avatar& avatar, const Eigen::MatrixXd& surface,
                          const BakedVertexAttributes& vertex_colours,
                          const std::vector<std::vector<int>>& members,
                          const TextureBakeOptions& opt = {});

}  // namespace ks
