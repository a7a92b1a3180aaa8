#pragma once
// Tile-based EWA splatting as in 3DGS, CPU backend: forward and backward.
// Backend-neutral interface: plain buffers in (ks::Gaussians, ks::Camera), plain buffers out.
// See docs/rasterizer.md for the exact conventions (pixel centres, clamps, culling, cut-offs).
//
// Templated on the scalar: float (Gaussians, RasterResult, RasterGrads) renders and trains;
// double (GaussiansD, RasterResultD, RasterGradsD) is the same code for the finite-difference
// tests. The sources, by idea: projection.hpp and sh.hpp (per-Gaussian forward / backward
// pairs), preprocess.cpp (project every Gaussian; the backward's chain rule per Gaussian),
// binning.cpp (depth sort, render records, tile lists), tiles_forward.cpp / tiles_backward.cpp
// (the per-tile compositing and its reverse), rasterizer.cpp (the two passes in order).
#include <cstdint>
#include <string>
#include <vector>

#include "core/aligned.hpp"
#include "core/camera.hpp"
#include "core/image.hpp"
#include "gaussians/gaussians.hpp"

namespace ks {

constexpr int kTileSize = 16;

// The CPU tile kernels: 4-pixel SSE2 chunks (the portable baseline), blocks of 4 x 2 pixels
// with AVX2, or the same blocks with AVX-512VL (the AVX2 kernels' code with 32 vector registers
// and mask registers). kAuto takes the best the CPU has (KS_RASTER_NO_AVX512=1 stops it at AVX2,
// KS_RASTER_NO_AVX2=1 at the baseline). The AVX2 and AVX-512 kernels give the same images and
// gradients, bit for bit; they fuse multiply-adds (the CPU must have FMA too), so the baseline's
// agree with theirs up to rounding (and the order of float sums). The double instantiation has
// one kernel (this setting is ignored there).
enum class RasterKernel { kAuto, kBaseline, kAvx2, kAvx512 };

struct RasterSettings {
  float background[3] = {0.f, 0.f, 0.f};
  float near_plane = 0.01f;
  float low_pass = 0.3f;  // added to the 2D covariance diagonal (pixels^2)
  RasterKernel kernel = RasterKernel::kAuto;
  // Colour and alpha only (playback, evaluation): none of the per-pixel state the backward pass
  // needs, which the compositing then neither accumulates nor writes (final_T, n_contrib and
  // entry_cells come back empty; rasterize_backward refuses such a result). The expected depth
  // is `depth`'s choice, in either forward.
  bool image_only = false;
  // Also the expected depth (RasterResultT::depth, sum of w_i z_i); off, the compositing neither
  // accumulates nor writes it (nothing in training or playback reads it: in-process A/B on the
  // bench scene, compositing x0.97 without it).
  bool depth = false;
};

// Whether this CPU can run RasterKernel::kAvx2 / kAvx512.
bool raster_avx2_available();
bool raster_avx512_available();
// A kernel by its name: "auto", "baseline", "avx2" or "avx512" (throws for any other).
RasterKernel raster_kernel_from_name(const std::string& name);
// The tile kernel `s` runs on this CPU: "baseline", "avx2" or "avx512" (kAuto resolved; throws
// as the rasterizer does for a kernel the CPU lacks).
const char* raster_kernel_name(const RasterSettings& s);

// Everything the forward pass produces; also the state the backward pass reuses.
// Reuse one RasterResult across frames: buffers are resized, not reallocated.
template <class T>
struct RasterResultT {
  ImageT<T> color;          // W x H x 3
  ImageT<T> alpha;          // W x H x 1
  ImageT<T> depth;          // W x H x 1, expected depth (sum of w_i z_i), not normalised by alpha;
                            // empty unless the settings asked for it (RasterSettings::depth)
  bool image_only = false;  // the settings' image_only of the forward that filled this
  // Per Gaussian (N).
  std::vector<int> radii;  // pixel radius ceil(3 sigma_max), 0 = not visible (culled)
  std::vector<T> depths;   // N camera-space z
  // 2N: the tiles a visible Gaussian's pixel rectangle touches, tx0 | tx1 << 16, ty0 | ty1 << 16
  std::vector<uint32_t> tile_rects;
  // packed[16 i ..] = the render record of Gaussian i, valid where radii > 0: [0, 2) mean2d
  // (pixels), [2, 5) conic (a, b, c of the inverse 2D covariance), [5] activated opacity, [6, 9)
  // colour (SH, clamped at 0), [9] depth, [10, 14) pixel rect x0 x1 y0 y1 inclusive, [14] the
  // channels the clamp cut (bits 1, 2, 4), [15] 0; as the projection wrote it into `records` (the
  // two swap; records is scratch after the forward). A record is 64 bytes: the arrays start on a
  // cache line, so each record lies in one line. The records are also the backward's
  // per-Gaussian state: it recomputes the 3D covariance from the parameters.
  LineAlignedVector<T> packed, records;
  // Per Gaussian, 12 values (written by a full float forward of Gaussians with SH degree > 0,
  // else empty): [3 c + a] the derivative of colour channel c (before the clamp at zero) with
  // respect to axis a of the unit view direction, where radii > 0; [9, 12) 0. The backward's
  // chain rule takes the view direction's gradient from these 9 values instead of reading the
  // SH coefficients again (192 bytes a Gaussian at degree 3).
  LineAlignedVector<T> color_dirs;
  std::vector<uint32_t> point_list;   // Gaussian ids, tile-major then depth order
  std::vector<uint32_t> tile_ranges;  // 2 * tiles: [start, end) into point_list
  // Per point_list entry (empty after an image_only forward): the tile's cells of 4 x 2 pixels
  // where the Gaussian contributed to a pixel, as bits; the backward visits only those.
  std::vector<uint32_t> entry_cells;
  std::vector<T> final_T;           // per pixel
  std::vector<uint32_t> n_contrib;  // per pixel: index one past the last contributor (in tile)
  // Scratch reused across frames (sorting, binning).
  std::vector<uint32_t> scratch_keys, scratch_ids, scratch_keys2, scratch_ids2, scratch_counts;
};

template <class T>
struct RasterGradsT {
  std::vector<T> means;           // 3N
  std::vector<T> log_scales;      // 3N
  std::vector<T> quats;           // 4N (w.r.t. the raw, un-normalised quaternion)
  std::vector<T> opacity_logits;  // N
  std::vector<T> sh;              // N*K*3
  std::vector<T> means2d;         // 2N (pixel space), for density control statistics
  std::vector<T> scratch;         // per-thread screen-space accumulators, reused
};

using RasterResult = RasterResultT<float>;
using RasterGrads = RasterGradsT<float>;
using RasterResultD = RasterResultT<double>;
using RasterGradsD = RasterGradsT<double>;

// Instantiated for float and double.
template <class T>
void rasterize_forward(const GaussiansT<T>& g, const Camera& cam, const RasterSettings& settings,
                       RasterResultT<T>& out);
// Means, rotations and opacity logits computed as the projection reads them, a chunk of Gaussians
// at a time, into scratch of the projection's (playback's posing: body/lbs.hpp LbsRanges), so
// that they never make a round trip through memory.
class GaussianSource {
 public:
  virtual ~GaussianSource() = default;
  // Gaussians [b, e) into means[3 (i - b) ..], quats[4 (i - b) ..], opacity_logits[i - b].
  // Called from the projection's threads for disjoint ranges; must not throw.
  virtual void fill(size_t b, size_t e, float* means, float* quats,
                    float* opacity_logits) const = 0;
};
// The forward with the means, rotations and opacities of `source`; `g` gives the rest (scales,
// SH) and the count (its own means, quats and opacities are not read). The same result as
// rasterize_forward on the Gaussians `source` describes, bit for bit.
void rasterize_forward(const Gaussians& g, const GaussianSource& source, const Camera& cam,
                       const RasterSettings& settings, RasterResult& out);
// Gradients of a loss given dL/dcolor (W x H x 3) and dL/dalpha (W x H x 1, may be empty).
// The gradients are written (not accumulated) into `grads`; its buffers are resized as needed.
template <class T>
void rasterize_backward(const GaussiansT<T>& g, const Camera& cam, const RasterSettings& settings,
                        const RasterResultT<T>& fwd, const ImageT<T>& dL_dcolor,
                        const ImageT<T>& dL_dalpha, RasterGradsT<T>& grads);

}  // namespace ks
