// The double instantiation uses 4-lane double vectors (32 bytes) on the baseline ISA.
#pragma GCC diagnostic ignored "-Wpsabi"
#include "raster/raster_double.hpp"

#include "raster/raster_impl.hpp"

namespace ks {

GaussiansD GaussiansD::from(const Gaussians& g) {
  GaussiansD d;
  d.sh_degree = g.sh_degree;
  d.means.assign(g.means.begin(), g.means.end());
  d.log_scales.assign(g.log_scales.begin(), g.log_scales.end());
  d.quats.assign(g.quats.begin(), g.quats.end());
  d.opacity_logits.assign(g.opacity_logits.begin(), g.opacity_logits.end());
  d.sh.assign(g.sh.begin(), g.sh.end());
  return d;
}

void rasterize_forward(const GaussiansD& g, const Camera& cam, const RasterSettings& settings,
                       RasterResultD& out) {
  raster_detail::forward_impl(g, cam, settings, out);
}

void rasterize_backward(const GaussiansD& g, const Camera& cam, const RasterSettings& settings,
                        const RasterResultD& fwd, const ImageD& dL_dcolor, const ImageD& dL_dalpha,
                        RasterGradsD& grads) {
  raster_detail::backward_impl(g, cam, settings, fwd, dL_dcolor, dL_dalpha, grads);
}

}  // namespace ks
