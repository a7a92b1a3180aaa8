// The two passes of the rasterizer in order (3DGS's rasterizer_impl.cu): forward = preprocess,
// sort and bin, composite tiles; backward = tiles in reverse, then the per-Gaussian chain rule.
#include "raster/rasterizer.hpp"

#include <omp.h>

#include "core/env.hpp"
#include "raster/raster_internal.hpp"

namespace ks {

bool raster_avx2_available() {
#if defined(__x86_64__) || defined(__i386__)
  // (The AVX2 kernels use FMA too: every AVX2 CPU but a few early ones has it.)
  static const bool ok = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return ok;
#else
  return false;
#endif
}

bool raster_avx512_available() {
#if defined(__x86_64__)
  static const bool ok = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
                         __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") &&
                         __builtin_cpu_supports("fma");
  return ok;
#else
  return false;
#endif
}

namespace raster {

Isa choose_isa(const RasterSettings& s) {
  switch (s.kernel) {
    case RasterKernel::kBaseline:
      return Isa::kBaseline;
    case RasterKernel::kAvx2:
      if (!raster_avx2_available())
        throw Error("rasterizer: the AVX2 kernel was asked for, but this CPU lacks AVX2 or FMA");
      return Isa::kAvx2;
    case RasterKernel::kAvx512:
      if (!raster_avx512_available())
        throw Error("rasterizer: the AVX-512 kernel was asked for, but this CPU has no AVX-512");
      return Isa::kAvx512;
    default: {
      static const bool no512 = env_flag("KS_RASTER_NO_AVX512");
      static const bool no2 = env_flag("KS_RASTER_NO_AVX2");
      if (raster_avx512_available() && !no512 && !no2) return Isa::kAvx512;
      if (raster_avx2_available() && !no2) return Isa::kAvx2;
      return Isa::kBaseline;
    }
  }
}

}  // namespace raster

RasterKernel raster_kernel_from_name(const std::string& name) {
  if (name == "auto") return RasterKernel::kAuto;
  if (name == "baseline") return RasterKernel::kBaseline;
  if (name == "avx2") return RasterKernel::kAvx2;
  if (name == "avx512") return RasterKernel::kAvx512;
  throw Error("rasterizer: no tile kernel named '" + name + "' (auto, baseline, avx2 or avx512)");
}

const char* raster_kernel_name(const RasterSettings& s) {
  switch (raster::choose_isa(s)) {
    case raster::Isa::kAvx512:
      return "avx512";
    case raster::Isa::kAvx2:
      return "avx2";
    default:
      return "baseline";
  }
}

namespace raster {
namespace {

template <class Img>
void shape_image(Img& img, int w, int h, int c) {
  img.width = w;
  img.height = h;
  img.channels = c;
  img.data.resize(size_t(w) * h * c);
}

}  // namespace
}  // namespace raster

namespace raster {
namespace {

template <class T>
void forward(const GaussiansT<T>& g, const GaussianSource* source, const Camera& camera,
             const RasterSettings& s, RasterResultT<T>& out) {
  check_gaussians(g);
  if (camera.width <= 0 || camera.height <= 0) throw Error("rasterizer: empty camera image");
  const CameraT<T> cam(camera);
  const int W = cam.W, H = cam.H;
  const size_t N = g.size();
  shape_image(out.color, W, H, 3);
  shape_image(out.alpha, W, H, 1);
  out.image_only = s.image_only;
  if (s.depth)
    shape_image(out.depth, W, H, 1);
  else
    out.depth = ImageT<T>();
  out.radii.resize(N);
  out.depths.resize(N);
  out.tile_rects.resize(2 * N);
  out.records.resize(size_t(raster::kRec) * N);
  if (std::is_same_v<T, float> && !s.image_only && g.sh_degree > 0)
    out.color_dirs.resize(size_t(raster::kColorDirs) * N);
  else
    out.color_dirs.clear();
  out.final_T.resize(s.image_only ? 0 : size_t(W) * H);
  out.n_contrib.resize(s.image_only ? 0 : size_t(W) * H);
  if (s.image_only) out.entry_cells.clear();  // (sized by the compositing otherwise)
  const int tiles_x = (W + kTS - 1) / kTS, tiles_y = (H + kTS - 1) / kTS;
  out.tile_ranges.resize(2 * size_t(tiles_x) * tiles_y);
  const Isa isa = std::is_same_v<T, float> ? choose_isa(s) : Isa::kBaseline;

  PhaseTimer timer;
  // 1. Cull + project + colour, one parallel pass.
  if constexpr (std::is_same_v<T, float>)
    preprocess_forward_simd(g, cam, s, isa, out, source);
  else
    preprocess_forward(g, cam, s, out);
  timer.mark("project");
  // 2-4. Depth order, render records, tile lists.
  sort_and_bin(out, tiles_x, tiles_y);
  // 5. Compositing, front to back, one tile per task.
  PhaseTimer timer2;
  const T bg[3] = {T(s.background[0]), T(s.background[1]), T(s.background[2])};
  composite_tiles(out, tiles_x, tiles_y, bg, isa);
  timer2.mark("composite");
}

}  // namespace
}  // namespace raster

template <class T>
void rasterize_forward(const GaussiansT<T>& g, const Camera& camera, const RasterSettings& s,
                       RasterResultT<T>& out) {
  raster::forward<T>(g, nullptr, camera, s, out);
}

void rasterize_forward(const Gaussians& g, const GaussianSource& source, const Camera& camera,
                       const RasterSettings& s, RasterResult& out) {
  raster::forward<float>(g, &source, camera, s, out);
}

template <class T>
void rasterize_backward(const GaussiansT<T>& g, const Camera& camera, const RasterSettings& s,
                        const RasterResultT<T>& fwd, const ImageT<T>& dLdc, const ImageT<T>& dLda,
                        RasterGradsT<T>& gr) {
  using namespace raster;
  check_gaussians(g);
  const CameraT<T> cam(camera);
  const int W = cam.W, H = cam.H;
  const size_t N = g.size();
  if (fwd.image_only)
    throw Error("rasterize_backward: the forward result is image_only (no backward state)");
  if (fwd.radii.size() != N || fwd.packed.size() != size_t(kRec) * N || fwd.color.width != W ||
      fwd.color.height != H || fwd.entry_cells.size() != fwd.point_list.size() ||
      (!fwd.color_dirs.empty() && fwd.color_dirs.size() != size_t(kColorDirs) * N))
    throw Error("rasterize_backward: forward result does not match the Gaussians / camera");
  if (dLdc.width != W || dLdc.height != H || dLdc.channels != 3)
    throw Error("rasterize_backward: dL/dcolor must be W x H x 3");
  const bool has_da = !dLda.data.empty();
  if (has_da && (dLda.width != W || dLda.height != H || dLda.channels != 1))
    throw Error("rasterize_backward: dL/dalpha must be W x H x 1 or empty");
  const int tiles_x = (W + kTS - 1) / kTS, tiles_y = (H + kTS - 1) / kTS;
  const int threads = omp_get_max_threads();
  const Isa isa = std::is_same_v<T, float> ? choose_isa(s) : Isa::kBaseline;
  const T bg[3] = {T(s.background[0]), T(s.background[1]), T(s.background[2])};
  PhaseTimer timer;
  backward_tiles(fwd, dLdc, dLda, bg, tiles_x, tiles_y, isa, threads, gr);
  timer.mark("backward tiles");
  if constexpr (std::is_same_v<T, float>)
    preprocess_backward_simd(g, cam, fwd, threads, isa, gr);
  else
    preprocess_backward(g, cam, fwd, threads, gr);
  timer.mark("backward per-Gaussian");
}

template void rasterize_forward(const GaussiansT<float>&, const Camera&, const RasterSettings&,
                                RasterResultT<float>&);
template void rasterize_forward(const GaussiansT<double>&, const Camera&, const RasterSettings&,
                                RasterResultT<double>&);
template void rasterize_backward(const GaussiansT<float>&, const Camera&, const RasterSettings&,
                                 const RasterResultT<float>&, const ImageT<float>&,
                                 const ImageT<float>&, RasterGradsT<float>&);
template void rasterize_backward(const GaussiansT<double>&, const Camera&, const RasterSettings&,
                                 const RasterResultT<double>&, const ImageT<double>&,
                                 const ImageT<double>&, RasterGradsT<double>&);

}  // namespace ks
