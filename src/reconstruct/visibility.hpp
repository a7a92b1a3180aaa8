#pragma once
// Which Gaussians a training frame can see, decided before decoding so that the decoders, the
// triplane and the rasterizer work only for those (issue 17). A depth test against the points
// themselves: the points (each Gaussian's centre from its last decode, posed for the frame) are
// projected into a coarse depth buffer of `cell` x `cell` pixel cells holding each cell's nearest
// depth; a point is hidden when it lies more than `depth_margin` behind the *farthest* of the
// nearest depths in the cells around its own (`reach` cells each side, plus its footprint's), so
// near an occluding edge (where a neighbouring cell sees the surface behind) and next to empty
// cells (the silhouette) nothing is hidden. Points off the image or behind the camera count as seen
// (the rasterizer decides). No normals are used, so open surfaces (the garment layer's tube) and
// Gaussians pulled away from their anchors are judged by where they are.
#include <cstdint>
#include <vector>

#include "core/camera.hpp"

namespace ks {

struct VisibilityOptions {
  // Decode and draw only the Gaussians a frame can see, from iteration start * iterations on
  // (before that every Gaussian, while the front surface is still translucent). Off by default:
  // 18-28 % faster steps, but 0.1-0.5 dB less full-frame PSNR on the test splits (Gaussians
  // hidden in most training frames, between the legs and inside a skirt, go untrained and show
  // in novel poses; docs/reconstruct.md, "Faster steps").
  bool enabled = false;
  float start = 0.1f;
  // Every this many steps (from start on) decodes and draws every Gaussian all the same, so that
  // the ones hidden in most frames (the inner thighs) still meet the offset and Laplacian
  // regularisers and the mask loss; 0 = never, 1 = every step (visibility has no effect).
  int whole_every = 0;
  // Widen each Gaussian's neighbourhood by its footprint (3 sigma projected, in cells): half the
  // full-frame loss on seed 2, but it hides fewer and the steps were no faster than without
  // visibility (docs/reconstruct.md).
  bool footprint = false;
  float depth_margin = 0.03f;  // metres behind the surface in front before a point is hidden
  int cell = 4;                // depth-buffer cell, pixels
  int reach = 1;               // cells each side compared with
};

// points: 3n world positions; sigmas: n world extents (a Gaussian's largest standard deviation)
// or nullptr. A point's footprint (3 sigma, projected) widens the cells it is compared with by
// as many cells, so a large Gaussian whose centre is covered but whose skirt reaches past the
// edge in front is not hidden. Writes the indices of the points not hidden (increasing) and
// returns their count. Throws ks::Error for a cell < 1 or a reach < 0.
int visible_points(const float* points, const float* sigmas, int n, const Camera& camera,
                   const VisibilityOptions& o, std::vector<int>* visible);

}  // namespace ks
