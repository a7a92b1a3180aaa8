#pragma once
// Double-precision instantiation of the rasterizer (same code as the float path, templated):
// used by the finite-difference gradient tests. Not meant for production rendering.
#include <cstdint>
#include <vector>

#include "raster/rasterizer.hpp"

namespace ks {

struct ImageD {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<double> data;
  ImageD() = default;
  ImageD(int w, int h, int c, double fill = 0.0)
      : width(w), height(h), channels(c), data(size_t(w) * h * c, fill) {}
};

struct GaussiansD {
  int sh_degree = 0;
  std::vector<double> means, log_scales, quats, opacity_logits, sh;
  size_t size() const { return opacity_logits.size(); }
  int coeffs() const { return sh_coeff_count(sh_degree); }
  static GaussiansD from(const Gaussians& g);
};

struct RasterResultD {
  ImageD color, alpha, depth;
  std::vector<int> radii;
  std::vector<double> means2d, conics, colors, depths, cov3d;
  std::vector<uint8_t> sh_clamped;
  std::vector<double> opacities, packed;
  std::vector<int> rects;
  std::vector<uint32_t> point_list, tile_ranges;
  std::vector<double> final_T;
  std::vector<uint32_t> n_contrib;
  std::vector<uint32_t> scratch_keys, scratch_ids, scratch_keys2, scratch_ids2, scratch_counts;
};

struct RasterGradsD {
  std::vector<double> means, log_scales, quats, opacity_logits, sh, means2d, scratch;
};

void rasterize_forward(const GaussiansD& g, const Camera& cam, const RasterSettings& settings,
                       RasterResultD& out);
void rasterize_backward(const GaussiansD& g, const Camera& cam, const RasterSettings& settings,
                        const RasterResultD& fwd, const ImageD& dL_dcolor, const ImageD& dL_dalpha,
                        RasterGradsD& grads);

}  // namespace ks
