#pragma once
// Linear blend skinning of Gaussians on the device (body/lbs.hpp's lbs_forward, one thread a
// Gaussian): the blended 3 x 4 transform of each Gaussian's top-k joints, its mean (plus the pose
// correctives' offset) moved by it, its rotation turned by the blend's quaternion, and its opacity
// logit set to kCulledOpacityLogit where back-face culling drops it. The same arithmetic as the
// CPU's, in single precision; the tests compare the two (tests/raster_cuda/).
#include <cuda_runtime.h>

namespace ks::cuda {

struct LbsArgs {
  int N = 0, K = 0;
  // Canonical Gaussians (3N, 4N, N) and their skin (K N joints, K N weights).
  const float *means = nullptr, *quats = nullptr, *logits = nullptr;
  const int* joints = nullptr;
  const float* weights = nullptr;
  const float* transforms = nullptr;  // 12 a joint: the skinning transform's top 3 x 4, row-major
  const float* offsets = nullptr;     // 3N pose-corrective offsets, or nullptr
  const float* normals = nullptr;     // 3N canonical unit normals for culling, or nullptr
  float eye[3] = {0, 0, 0};
  float threshold = 1.f;  // cull where cos(normal, mean - eye) > threshold
  float culled_logit = 0.f;
  // Posed outputs (3N, 4N, N).
  float *out_means = nullptr, *out_quats = nullptr, *out_logits = nullptr;
};

// Queues the kernel on `stream`; returns the launch's error.
cudaError_t launch_lbs(const LbsArgs& a, cudaStream_t stream);

}  // namespace ks::cuda
