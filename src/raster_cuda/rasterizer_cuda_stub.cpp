// The CUDA rasterizer's entry points in a build without CUDA (CMake's KS_CUDA off, the
// default): nothing runs on a GPU, and every entry point says how to get one.
#include "core/error.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace ks::cuda {

struct RasterizerCuda::State {};

namespace {
[[noreturn]] void no_cuda() {
  throw Error(
      "--device cuda: this build has no CUDA backend (configure with cmake -DKS_CUDA=ON on a "
      "machine with nvcc; docs/rasterizer_cuda.md)");
}
}  // namespace

bool raster_cuda_compiled() {
  return false;
}
int raster_cuda_devices() {
  return 0;
}
std::string raster_cuda_describe() {
  return "this build has no CUDA backend (cmake -DKS_CUDA=ON)";
}

RasterizerCuda::RasterizerCuda() {
  no_cuda();
}
RasterizerCuda::~RasterizerCuda() = default;
void RasterizerCuda::upload(const Gaussians&) {
  no_cuda();
}
void RasterizerCuda::upload_skinned(const Gaussians&, const std::vector<int>&,
                                    const std::vector<float>&, const std::vector<float>&) {
  no_cuda();
}
void RasterizerCuda::pose(const std::vector<Eigen::Matrix4d>&, const float*, const BackfaceCull*) {
  no_cuda();
}
void RasterizerCuda::download_gaussians(Gaussians&) const {
  no_cuda();
}
void RasterizerCuda::forward(const Camera&, const RasterSettings&) {
  no_cuda();
}
void RasterizerCuda::download(RasterResult&, bool) const {
  no_cuda();
}
void RasterizerCuda::backward(const Image&, const Image&) {
  no_cuda();
}
void RasterizerCuda::download_grads(RasterGrads&) const {
  no_cuda();
}
void RasterizerCuda::synchronize() const {
  no_cuda();
}
float RasterizerCuda::last_forward_ms() const {
  no_cuda();
}
float RasterizerCuda::last_backward_ms() const {
  no_cuda();
}
size_t RasterizerCuda::last_tile_entries() const {
  no_cuda();
}

}  // namespace ks::cuda
