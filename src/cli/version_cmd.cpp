// `kinesplat info`: build information.
#include <cstdio>

#include "cli/registry.hpp"
#include "raster/rasterizer.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace {
ks::cli::CommandGroup group(1000, [](CLI::App& app) {
  auto* sub = app.add_subcommand("info", "Print build information");
  sub->callback([] {
#ifdef __AVX512F__
    const char* isa = "avx512";
#elif defined(__AVX2__)
    const char* isa = "avx2";
#else
    const char* isa = "baseline x86-64";
#endif
    std::printf("kinesplat 0.1.0 (C++20, compiled for %s)\n", isa);
    ks::RasterSettings s;
    std::printf("rasterizer tile kernel on this CPU: %s\n", ks::raster_kernel_name(s));
    std::printf("CUDA rasterizer: %s\n", ks::cuda::raster_cuda_compiled()
                                             ? ks::cuda::raster_cuda_describe().c_str()
                                             : "not in this build (cmake -DKS_CUDA=ON)");
  });
});
}  // namespace
