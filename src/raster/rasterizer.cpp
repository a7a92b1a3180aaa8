// The AVX2 kernels use 8-lane float vectors (32 bytes); internal helpers only.
#pragma GCC diagnostic ignored "-Wpsabi"
#include "raster/rasterizer.hpp"

#include "raster/raster_impl.hpp"

namespace ks {

void rasterize_forward(const Gaussians& g, const Camera& cam, const RasterSettings& settings,
                       RasterResult& out) {
  raster_detail::forward_impl(g, cam, settings, out);
}

void rasterize_backward(const Gaussians& g, const Camera& cam, const RasterSettings& settings,
                        const RasterResult& fwd, const Image& dL_dcolor, const Image& dL_dalpha,
                        RasterGrads& grads) {
  raster_detail::backward_impl(g, cam, settings, fwd, dL_dcolor, dL_dalpha, grads);
}

}  // namespace ks
