#pragma once
// Tile-based EWA splatting as in 3DGS, CPU backend: forward and backward.
// Backend-neutral interface: plain buffers in (ks::Gaussians, ks::Camera), plain buffers out.
// See docs/rasterizer.md for the exact conventions (pixel centres, clamps, culling, cut-offs).
#include <cstdint>
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "gaussians/gaussians.hpp"

namespace ks {

constexpr int kTileSize = 16;

struct RasterSettings {
  float background[3] = {0.f, 0.f, 0.f};
  float near_plane = 0.01f;
  float low_pass = 0.3f;  // added to the 2D covariance diagonal (pixels^2)
};

// Everything the forward pass produces; also the state the backward pass reuses.
// Reuse one RasterResult across frames: buffers are resized, not reallocated.
struct RasterResult {
  Image color;  // W x H x 3
  Image alpha;  // W x H x 1
  Image depth;  // W x H x 1, expected depth (sum of w_i z_i), not normalised by alpha
  // Per Gaussian (N).
  std::vector<int> radii;      // pixel radius ceil(3 sigma_max), 0 = not visible (culled)
  std::vector<float> means2d;  // 2N, pixel coordinates
  // Internal state for backward (projected conics, colours, tile lists, per-pixel counts).
  std::vector<float> conics;        // 3N (a, b, c) of the inverse 2D covariance
  std::vector<float> colors;        // 3N evaluated SH colours
  std::vector<float> depths;        // N camera-space z
  std::vector<float> cov3d;         // 6N (xx, xy, xz, yy, yz, zz)
  std::vector<uint8_t> sh_clamped;  // 3N
  std::vector<float> opacities;     // N activated opacity
  std::vector<int> rects;           // 4N pixel bounding box x0, x1, y0, y1 (inclusive)
  // Visible Gaussians in depth order: scratch_ids[rank] = Gaussian id, packed[16 rank ..] =
  // render record (mean2d, conic, opacity, rgb, depth, pixel rect).
  std::vector<float> packed;
  std::vector<uint32_t> point_list;   // depth ranks (see packed), tile-major then depth
  std::vector<uint32_t> tile_ranges;  // 2 * tiles: [start, end) into point_list
  std::vector<float> final_T;         // per pixel
  std::vector<uint32_t> n_contrib;    // per pixel: index one past the last contributor (in tile)
  // Scratch reused across frames (sorting, binning).
  std::vector<uint32_t> scratch_keys, scratch_ids, scratch_keys2, scratch_ids2, scratch_counts;
};

struct RasterGrads {
  std::vector<float> means;           // 3N
  std::vector<float> log_scales;      // 3N
  std::vector<float> quats;           // 4N (w.r.t. the raw, un-normalised quaternion)
  std::vector<float> opacity_logits;  // N
  std::vector<float> sh;              // N*K*3
  std::vector<float> means2d;         // 2N (pixel space), for density control statistics
  std::vector<float> scratch;         // per-thread screen-space accumulators, reused
};

void rasterize_forward(const Gaussians& g, const Camera& cam, const RasterSettings& settings,
                       RasterResult& out);
// Gradients of a loss given dL/dcolor (W x H x 3) and dL/dalpha (W x H x 1, may be empty).
// The gradients are written (not accumulated) into `grads`; its buffers are resized as needed.
void rasterize_backward(const Gaussians& g, const Camera& cam, const RasterSettings& settings,
                        const RasterResult& fwd, const Image& dL_dcolor, const Image& dL_dalpha,
                        RasterGrads& grads);

}  // namespace ks
