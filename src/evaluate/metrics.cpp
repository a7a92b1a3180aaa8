#include "evaluate/metrics.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "reconstruct/losses.hpp"

namespace ks {

namespace {

void check(const Image& a, const Image& b, const Image* mask) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels)
    throw Error("metrics: image sizes differ (" + std::to_string(a.width) + "x" +
                std::to_string(a.height) + "x" + std::to_string(a.channels) + " vs " +
                std::to_string(b.width) + "x" + std::to_string(b.height) + "x" +
                std::to_string(b.channels) + ")");
  if (a.empty()) throw Error("metrics: empty image");
  if (mask && (mask->width != a.width || mask->height != a.height || mask->channels != 1))
    throw Error("metrics: the mask must be one channel of the image's size");
}

double psnr_from_mse(double mse) {
  if (mse <= 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(1.0 / mse);
}

double mse(const Image& a, const Image& b, const Image* mask) {
  double s = 0;
  size_t n = 0;
  const int c = a.channels;
  for (size_t p = 0; p < a.pixel_count(); ++p) {
    if (mask && mask->data[p] <= 0.5f) continue;
    for (int k = 0; k < c; ++k) {
      const double d = double(a.data[p * c + k]) - double(b.data[p * c + k]);
      s += d * d;
    }
    n += c;
  }
  return n ? s / double(n) : std::numeric_limits<double>::quiet_NaN();
}

std::vector<double> to_double(const Image& a) {
  return {a.data.begin(), a.data.end()};
}

}  // namespace

double psnr(const Image& a, const Image& b) {
  check(a, b, nullptr);
  return psnr_from_mse(mse(a, b, nullptr));
}

double psnr_masked(const Image& a, const Image& b, const Image& mask) {
  check(a, b, &mask);
  const double m = mse(a, b, &mask);
  return std::isnan(m) ? m : psnr_from_mse(m);
}

double ssim(const Image& a, const Image& b) {
  check(a, b, nullptr);
  auto x = to_double(a), y = to_double(b);
  return ssim<double>(x.data(), y.data(), a.width, a.height, a.channels, nullptr, 0.0, nullptr);
}

double ssim_masked(const Image& a, const Image& b, const Image& mask) {
  check(a, b, &mask);
  auto x = to_double(a), y = to_double(b);
  const double s =
      ssim_masked<double>(x.data(), y.data(), mask.data.data(), a.width, a.height, a.channels);
  return s < -0.5 ? std::numeric_limits<double>::quiet_NaN() : s;
}

ImageMetrics compute_metrics(const Image& render, const Image& truth, const Image& mask) {
  check(render, truth, &mask);
  ImageMetrics m;
  auto x = to_double(render), y = to_double(truth);
  std::vector<double> map;
  m.ssim = ssim<double>(x.data(), y.data(), render.width, render.height, render.channels, &map, 0.0,
                        nullptr);
  double s = 0;
  size_t n = 0;
  const int c = render.channels;
  for (size_t p = 0; p < render.pixel_count(); ++p) {
    if (mask.data[p] <= 0.5f) continue;
    for (int k = 0; k < c; ++k) s += map[p * c + k];
    n += c;
  }
  m.ssim_masked = n ? s / double(n) : std::numeric_limits<double>::quiet_NaN();
  m.psnr = psnr_from_mse(mse(render, truth, nullptr));
  const double mm = mse(render, truth, &mask);
  m.psnr_masked = std::isnan(mm) ? mm : psnr_from_mse(mm);
  return m;
}

}  // namespace ks
