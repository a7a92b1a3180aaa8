#pragma once
// The rasterizer on an NVIDIA GPU (CUDA), beside the CPU one (raster/rasterizer.hpp), which stays
// the reference: the same conventions (docs/rasterizer.md "Conventions": culling, the low-pass,
// the exact alpha box, alpha = min(0.99, o G), the 1e-4 transmittance stop, depth order with
// ties by id), the same outputs (colour, alpha, the expected depth on request, radii, depths)
// and the same gradients (means, log-scales, raw quaternions, opacity logits, SH coefficients,
// and the 2D means' for density control). Compiled when CMake's KS_CUDA is on (nvcc present);
// without it every entry point here says so (raster_cuda_compiled() is false, the constructor
// throws).
//
// The Gaussians and every intermediate stay on the device between calls: upload once, run the
// forward / backward as often as needed, and download only what the caller reads (as training
// and playback on a GPU would). docs/rasterizer_cuda.md gives the kernels and their figures.
#include <Eigen/Core>
#include <Eigen/StdVector>
#include <memory>
#include <string>
#include <vector>

#include "body/lbs.hpp"
#include "core/camera.hpp"
#include "core/image.hpp"
#include "gaussians/gaussians.hpp"
#include "raster/rasterizer.hpp"

namespace ks::cuda {

// Whether this build has the CUDA backend (CMake -DKS_CUDA=ON).
bool raster_cuda_compiled();
// CUDA devices this process can use: 0 without the backend, a driver or a GPU.
int raster_cuda_devices();
// Device 0 in a line ("NVIDIA H200, 132 SMs, 139.8 GiB, compute 9.0"), or why there is none.
std::string raster_cuda_describe();

class RasterizerCuda {
 public:
  // On device 0; throws ks::Error when the build has no CUDA or no device can be used.
  RasterizerCuda();
  ~RasterizerCuda();
  RasterizerCuda(const RasterizerCuda&) = delete;
  RasterizerCuda& operator=(const RasterizerCuda&) = delete;

  // Copies the Gaussians to the device (they stay there until the next upload). Throws for
  // arrays of inconsistent sizes or an SH degree outside 0..3.
  void upload(const Gaussians& g);
  // Posing on the device (playback): the canonical Gaussians (their scales and SH go straight
  // to the rasterizer's arrays: posing keeps them), their top-k skin (K = skin_joints.size() / N
  // joints and weights each, as lbs_forward takes them) and, for back-face culling, their
  // anchors' canonical unit normals (3N, or empty: no culling), copied once. ks::Error on
  // inconsistent sizes, a negative joint or an SH degree outside 0..3.
  void upload_skinned(const Gaussians& canonical, const std::vector<int>& skin_joints,
                      const std::vector<float>& skin_weights, const std::vector<float>& normals);
  // Poses the Gaussians of the last upload_skinned on the device as lbs_forward does on the CPU
  // (body/lbs.hpp; single precision, so equal up to rounding): the skinning transforms (one a
  // joint, more than the largest skin joint), the pose correctives' offsets (3N, or nullptr) and
  // back-face culling (nullptr: none; the uploaded normals are used, cull->normals is not read;
  // the threshold must be in [0, 1]). Only the transforms (48 bytes a joint) and the offsets
  // travel. The next forward renders the posed Gaussians.
  void pose(const std::vector<Eigen::Matrix4d>& transforms, const float* pose_offsets,
            const BackfaceCull* cull);
  // The Gaussians the device holds now (those of the last upload or pose).
  void download_gaussians(Gaussians& out) const;
  // The forward pass on the device, asynchronously (nothing comes back to the host; the call
  // returns once the kernels are queued, after one small copy: the number of tile entries).
  // settings.kernel is ignored; settings.image_only skips the backward's per-pixel state and
  // the expected depth is made only with settings.depth, as on the CPU.
  void forward(const Camera& cam, const RasterSettings& settings);
  // The last forward's images (colour, alpha, and depth with settings.depth) and, with
  // per_gaussian, the radii and depths into `out` (its other fields are left alone; without
  // per_gaussian radii and depths are left empty: playback needs the images only).
  void download(RasterResult& out, bool per_gaussian = true) const;
  // The backward pass of the last full forward, given dL/dcolour (W x H x 3) and dL/dalpha
  // (W x H x 1, or empty): the gradients stay on the device until download_grads.
  void backward(const Image& dL_dcolor, const Image& dL_dalpha);
  // The gradients of the last backward into `grads` (written, not accumulated; its scratch is
  // left alone), in the CPU rasterizer's layout.
  void download_grads(RasterGrads& grads) const;
  // Waits for everything queued (for timing).
  void synchronize() const;
  // Milliseconds of the last forward / backward between their first and last kernel, from CUDA
  // events (valid after synchronize()).
  float last_forward_ms() const;
  float last_backward_ms() const;
  // Entries in the last forward's tile lists (a Gaussian counted once per tile it touches).
  size_t last_tile_entries() const;

 private:
  struct State;
  std::unique_ptr<State> st_;
};

}  // namespace ks::cuda
