#pragma once
// Image quality metrics: PSNR and SSIM (11x11 Gaussian window, sigma 1.5, the same SSIM as the
// training loss in reconstruct/losses.hpp), over the full frame and inside a mask (pixels with
// mask > 0.5: masked PSNR = PSNR of the MSE over those pixels, masked SSIM = mean of the SSIM map
// over those pixels). Images are RGB in [0, 1], same size.
#include "core/image.hpp"

namespace ks {

struct ImageMetrics {
  double psnr = 0, ssim = 0;                // full frame
  double psnr_masked = 0, ssim_masked = 0;  // inside the mask (NaN if the mask is empty)
};

double psnr(const Image& a, const Image& b);  // throws on size mismatch
double psnr_masked(const Image& a, const Image& b, const Image& mask);
double ssim(const Image& a, const Image& b);
double ssim_masked(const Image& a, const Image& b, const Image& mask);
// All four at once (one SSIM map).
ImageMetrics compute_metrics(const Image& render, const Image& truth, const Image& mask);

}  // namespace ks
