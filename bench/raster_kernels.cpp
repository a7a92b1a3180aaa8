// The rasterizer on the bench scene (`kinesplat bench raster`'s avatar-like cloud and camera)
// with one tile kernel, chosen by name: forward, image-only forward and forward + backward, the
// median of N frames. It needs nothing but the rasterizer, so that bench/raster_static_build.sh
// can link it statically for a machine without the project's packages (docs/rasterizer.md,
// "AVX-512 measured").
//   raster_kernels [auto|baseline|avx2|avx512] [frames=20] [gaussians=110000]
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "core/error.hpp"
#include "raster/avatar_cloud.hpp"
#include "raster/rasterizer.hpp"

namespace {

double since_ms(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const char* name = argc > 1 ? argv[1] : "auto";
  const int frames = argc > 2 ? std::atoi(argv[2]) : 20;
  const int n = argc > 3 ? std::atoi(argv[3]) : 110000;
  ks::RasterSettings s;
  try {
    s.kernel = ks::raster_kernel_from_name(name);
  } catch (const ks::Error&) {
    std::fprintf(stderr,
                 "usage: raster_kernels [auto|baseline|avx2|avx512] [frames] [gaussians]\n");
    return 2;
  }
  if (frames < 1 || n < 1) {
    std::fprintf(stderr, "raster_kernels: frames and gaussians must be positive\n");
    return 2;
  }
  try {
    const ks::Gaussians g = ks::make_avatar_cloud(size_t(n), 1);
    const ks::Camera cam = ks::avatar_camera(512, 768);
    ks::RasterResult r;
    ks::RasterGrads gr;
    ks::Image dc(cam.width, cam.height, 3), da;
    for (size_t i = 0; i < dc.data.size(); ++i) dc.data[i] = float((i * 7919) % 1000) * 1e-6f;
    std::vector<double> fwd, img, both;
    for (int i = 0; i < frames + 2; ++i) {  // two warm-up frames
      s.image_only = false;
      auto t = std::chrono::steady_clock::now();
      ks::rasterize_forward(g, cam, s, r);
      const double tf = since_ms(t);
      ks::rasterize_backward(g, cam, s, r, dc, da, gr);
      const double tb = since_ms(t);
      s.image_only = true;
      t = std::chrono::steady_clock::now();
      ks::rasterize_forward(g, cam, s, r);
      const double ti = since_ms(t);
      if (i >= 2) fwd.push_back(tf), both.push_back(tb), img.push_back(ti);
    }
    std::printf(
        "kernel %s, %d threads, %d Gaussians, 512x768: forward %.2f ms, image only %.2f ms, "
        "forward+backward %.2f ms (medians of %d frames)\n",
        name, omp_get_max_threads(), n, median(fwd), median(img), median(both), frames);
  } catch (const ks::Error& e) {
    std::fprintf(stderr, "raster_kernels: %s\n", e.what());
    return 1;
  }
  return 0;
}
