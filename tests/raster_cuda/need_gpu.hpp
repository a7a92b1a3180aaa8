#pragma once
// Skips a test, saying why, where this build has no CUDA backend or the machine no device (CI).
#include <gtest/gtest.h>

#include "raster_cuda/rasterizer_cuda.hpp"

#define KS_NEED_GPU()                                                           \
  do {                                                                          \
    if (ks::cuda::raster_cuda_devices() == 0)                                   \
      GTEST_SKIP() << "needs a CUDA GPU: " << ks::cuda::raster_cuda_describe(); \
  } while (0)
