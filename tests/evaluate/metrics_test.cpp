#include "evaluate/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.hpp"

namespace ks {

TEST(Metrics, PsnrAndSsimKnownValues) {
  Image a(20, 16, 3, 0.5f), b(20, 16, 3, 0.5f), mask(20, 16, 1, 0.f);
  EXPECT_TRUE(std::isinf(psnr(a, b)));
  EXPECT_NEAR(ssim(a, b), 1.0, 1e-12);
  // Constant error 0.1 everywhere: MSE 0.01 -> 20 dB.
  for (auto& v : b.data) v = 0.6f;
  EXPECT_NEAR(psnr(a, b), 20.0, 1e-4);
  // Error only in the left half; mask selects the right half: masked PSNR infinite.
  b = a;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 10; ++x)
      for (int c = 0; c < 3; ++c) b.at(x, y, c) = 0.7f;
  for (int y = 0; y < 16; ++y)
    for (int x = 10; x < 20; ++x) mask.at(x, y, 0) = 1.f;
  EXPECT_NEAR(psnr(a, b), 10 * std::log10(1.0 / (0.04 * 0.5)), 1e-3);
  EXPECT_TRUE(std::isinf(psnr_masked(a, b, mask)));
  ImageMetrics m = compute_metrics(b, a, mask);
  EXPECT_NEAR(m.psnr, psnr(a, b), 1e-9);
  EXPECT_NEAR(m.ssim, ssim(b, a), 1e-9);
  EXPECT_NEAR(m.ssim_masked, ssim_masked(b, a, mask), 1e-9);
  EXPECT_LT(m.ssim, 1.0);
  EXPECT_GT(m.ssim_masked, m.ssim);  // the masked half is mostly unaffected
  Image empty_mask(20, 16, 1, 0.f);
  EXPECT_TRUE(std::isnan(psnr_masked(a, b, empty_mask)));
}

TEST(Metrics, RejectsMismatchedSizes) {
  Image a(20, 16, 3), b(16, 20, 3), m(20, 16, 3);
  EXPECT_THROW(psnr(a, b), Error);
  EXPECT_THROW(ssim(a, b), Error);
  EXPECT_THROW(psnr_masked(a, a, m), Error);
}

}  // namespace ks
