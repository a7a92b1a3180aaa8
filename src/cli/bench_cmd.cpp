// `kinesplat bench raster`: rasterizer throughput on a reproducible avatar-like cloud.
#include <omp.h>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/math.hpp"
#include "core/speed_probe.hpp"
#include "gaussians/ply.hpp"
#include "raster/avatar_cloud.hpp"
#include "raster/rasterizer.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace {

struct Opts {
  size_t gaussians = 110000;
  int width = 512, height = 768, frames = 10, threads = 0;
  bool backward = false, probe = true;
  std::string ply, camera, save_ply, save_camera, kernel = "auto", device = "cpu";
};

// Upstream gradients for the backward: small, fixed, reproducible.
void make_upstream(const ks::Camera& cam, ks::Image& dc, ks::Image& da) {
  dc = ks::Image(cam.width, cam.height, 3);
  da = ks::Image(cam.width, cam.height, 1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(-1e-3f, 1e-3f);
  for (float& v : dc.data) v = U(rng);
  for (float& v : da.data) v = U(rng);
}

// Visible Gaussians and the image's mean alpha (percent).
void scene_summary(const std::vector<int>& radii, const ks::Image& alpha, size_t& visible,
                   double& coverage) {
  visible = 0;
  for (int rad : radii) visible += rad > 0;
  double cov = 0;
  for (float a : alpha.data) cov += a;
  coverage = 100.0 * cov / double(std::max<size_t>(1, alpha.data.size()));
}

// The three timings' lines (per-frame wall times in ms), each with the caller's note; `digits`
// and `fps_digits` after the point for milliseconds and frames a second.
struct Timings {
  std::vector<double> fwd, img, both;
  std::string fwd_note, img_note, both_note;
  int digits = 2, fps_digits = 1;
};

void print_timings(const Timings& t, int frames) {
  const int d = t.digits, fd = t.fps_digits;
  auto least = [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); };
  const double mf = ks::median(t.fwd), mi = ks::median(t.img);
  std::printf("forward: median %.*f ms, min %.*f ms over %d frames%s\n", d, mf, d, least(t.fwd),
              frames, t.fwd_note.c_str());
  std::printf("forward, image only (playback): median %.*f ms, min %.*f ms (%.*f FPS%s)\n", d, mi,
              d, least(t.img), fd, 1000.0 / mi, t.img_note.c_str());
  if (!t.both.empty()) {
    const double mb = ks::median(t.both);
    std::printf("forward+backward: median %.*f ms, min %.*f ms over %d frames%s\n", d, mb, d,
                least(t.both), frames, t.both_note.c_str());
    std::printf("forward %.*f FPS, forward+backward %.*f ms\n", fd, 1000.0 / mf, d, mb);
  } else {
    std::printf("forward %.*f FPS\n", fd, 1000.0 / mf);
  }
}

std::string note(const char* fmt, double v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// The same measurements on the GPU (--device cuda): the Gaussians uploaded once, each frame's
// time from the host (the call until the GPU is done, the copy of dL/dcolour and dL/dalpha
// included for the backward) and from CUDA events around the kernels.
void run_cuda(const Opts& o, const ks::Gaussians& g, const ks::Camera& cam) {
  using clock = std::chrono::steady_clock;
  ks::cuda::RasterizerCuda r;  // throws, saying why, without a build or a device
  ks::RasterSettings s;
  ks::Image dc, da;
  make_upstream(cam, dc, da);
  r.upload(g);
  for (int w = 0; w < 3; ++w) {  // warm-up: buffers sized, kernels loaded
    r.forward(cam, s);
    if (o.backward) r.backward(dc, da);
    r.synchronize();
  }
  auto ms_since = [](clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(clock::now() - t0).count();
  };
  Timings t;
  t.digits = 3, t.fps_digits = 0;
  std::vector<double> fwd_k, img_k, both_k;
  for (int f = 0; f < o.frames; ++f) {
    auto t0 = clock::now();
    r.forward(cam, s);
    r.synchronize();
    t.fwd.push_back(ms_since(t0));
    fwd_k.push_back(r.last_forward_ms());
  }
  const size_t entries = r.last_tile_entries();
  ks::RasterResult res;
  r.download(res);
  ks::RasterSettings si = s;
  si.image_only = true;
  for (int f = 0; f < o.frames; ++f) {
    auto t0 = clock::now();
    r.forward(cam, si);
    r.synchronize();
    t.img.push_back(ms_since(t0));
    img_k.push_back(r.last_forward_ms());
  }
  if (o.backward)
    for (int f = 0; f < o.frames; ++f) {
      auto t0 = clock::now();
      r.forward(cam, s);
      r.backward(dc, da);
      r.synchronize();
      t.both.push_back(ms_since(t0));
      both_k.push_back(r.last_forward_ms() + r.last_backward_ms());
    }
  size_t visible;
  double coverage;
  scene_summary(res.radii, res.alpha, visible, coverage);
  std::printf(
      "gaussians %zu (visible %zu), %dx%d, device cuda (%s), tile entries %zu, coverage "
      "%.1f%%\n",
      g.size(), visible, cam.width, cam.height, ks::cuda::raster_cuda_describe().c_str(), entries,
      coverage);
  t.fwd_note = note(" (kernels %.3f ms)", ks::median(fwd_k));
  t.img_note = note("; kernels %.3f ms", ks::median(img_k));
  if (o.backward)
    t.both_note = note(" (kernels %.3f ms; the rest is the copy of dL/dcolour and dL/dalpha)",
                       ks::median(both_k));
  print_timings(t, o.frames);
}

void run(const Opts& o) {
  using clock = std::chrono::steady_clock;
  if (o.gaussians == 0 || o.width <= 0 || o.height <= 0 || o.frames <= 0)
    throw ks::Error("bench raster: --gaussians, --width, --height and --frames must be positive");
  if (o.threads > 0) omp_set_num_threads(o.threads);
  // A given scene replaces the generated cloud / camera (the image size is then the camera's).
  const ks::Gaussians g =
      o.ply.empty() ? ks::make_avatar_cloud(o.gaussians, 1) : ks::read_ply(o.ply);
  const ks::Camera cam =
      o.camera.empty() ? ks::avatar_camera(o.width, o.height) : ks::Camera::load(o.camera);
  if (!o.save_ply.empty()) ks::write_ply(o.save_ply, g);
  if (!o.save_camera.empty()) cam.save(o.save_camera);
  if (o.device == "cuda") return run_cuda(o, g, cam);
  ks::RasterSettings s;
  s.kernel = ks::raster_kernel_from_name(o.kernel);
  const char* kernel = ks::raster_kernel_name(s);  // throws for one the CPU lacks
  ks::RasterResult r;
  ks::RasterGrads gr;
  ks::Image dc, da;
  make_upstream(cam, dc, da);
  auto ms_since = [](clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(clock::now() - t0).count();
  };
  rasterize_forward(g, cam, s, r);  // warm-up: buffers sized, threads started
  if (o.backward) rasterize_backward(g, cam, s, r, dc, da, gr);
  auto cpu_ms = [] {
    timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  };
  // The machine's state before and after the timings (a shared host's neighbours and clock
  // changes slow every figure alike; bench/speed_rounds.sh sorts its rounds by this).
  const ks::SpeedProbe probe0 = o.probe ? ks::speed_probe() : ks::SpeedProbe{};
  Timings t;
  const double cpu0 = cpu_ms();
  for (int f = 0; f < o.frames; ++f) {
    auto t0 = clock::now();
    rasterize_forward(g, cam, s, r);
    t.fwd.push_back(ms_since(t0));
  }
  const double cpu_fwd = (cpu_ms() - cpu0) / o.frames;
  // The playback forward: colour and alpha only.
  ks::RasterSettings si = s;
  si.image_only = true;
  ks::RasterResult ri;
  rasterize_forward(g, cam, si, ri);
  for (int f = 0; f < o.frames; ++f) {
    auto t0 = clock::now();
    rasterize_forward(g, cam, si, ri);
    t.img.push_back(ms_since(t0));
  }
  const double cpu1 = cpu_ms();
  if (o.backward)
    for (int f = 0; f < o.frames; ++f) {
      auto t0 = clock::now();
      rasterize_forward(g, cam, s, r);
      rasterize_backward(g, cam, s, r, dc, da, gr);
      t.both.push_back(ms_since(t0));
    }
  const double cpu_both = o.backward ? (cpu_ms() - cpu1) / o.frames : 0.0;
  size_t visible;
  double coverage;
  scene_summary(r.radii, r.alpha, visible, coverage);
  std::printf(
      "gaussians %zu (visible %zu), %dx%d, threads %d, tile entries %zu, coverage %.1f%%, kernel "
      "%s\n",
      g.size(), visible, cam.width, cam.height, omp_get_max_threads(), r.point_list.size(),
      coverage, kernel);
  if (o.probe) {
    const ks::SpeedProbe probe1 = ks::speed_probe();
    std::printf(
        "machine speed probe: %.2f ms before, %.2f ms after (a fixed arithmetic load on %d "
        "threads, no memory traffic; larger = the machine slower)\n",
        probe0.ms, probe1.ms, probe1.threads);
  }
  t.fwd_note = note(" (CPU time %.1f ms/frame)", cpu_fwd);
  if (o.backward) t.both_note = note(" (CPU time %.1f ms/frame)", cpu_both);
  print_timings(t, o.frames);
}

ks::cli::CommandGroup group(900, [](CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Benchmarks");
  bench->require_subcommand(1);
  auto* sub = bench->add_subcommand(
      "raster", "Rasterizer speed on a reproducible avatar-like Gaussian cloud (portrait framing)");
  auto o = std::make_shared<Opts>();
  sub->add_option("--gaussians", o->gaussians, "number of Gaussians")->capture_default_str();
  sub->add_option("--width", o->width, "image width")->capture_default_str();
  sub->add_option("--height", o->height, "image height")->capture_default_str();
  sub->add_flag("--backward", o->backward, "also time forward + backward");
  sub->add_option("--frames", o->frames, "timed frames (median reported)")->capture_default_str();
  sub->add_option("--threads", o->threads, "OpenMP threads (0 = default)");
  sub->add_flag("!--no-probe", o->probe,
                "skip the machine speed probe (CPU: a fixed arithmetic load timed before and "
                "after, about 0.1 s each, printed beside the figures)");
  sub->add_option("--kernel", o->kernel,
                  "tile kernel: auto (AVX-512 where the CPU has it, else AVX2 where it has that, "
                  "else baseline), baseline, avx2 or avx512 (an error where the CPU lacks it)")
      ->check(CLI::IsMember({"auto", "baseline", "avx2", "avx512"}))
      ->capture_default_str();
  sub->add_option("--device", o->device,
                  "cpu, or cuda: the GPU rasterizer (a build with -DKS_CUDA=ON and an NVIDIA GPU; "
                  "--threads and --kernel do not apply)")
      ->check(CLI::IsMember({"cpu", "cuda"}))
      ->capture_default_str();
  sub->add_option("--ply", o->ply,
                  "time this 3DGS .ply instead of the generated cloud (--gaussians is ignored)");
  sub->add_option(
      "--camera", o->camera,
      "time this camera JSON instead of the portrait camera (its size replaces --width/--height)");
  sub->add_option("--save-ply", o->save_ply, "also write the cloud as a 3DGS .ply");
  sub->add_option("--save-camera", o->save_camera, "also write the camera as JSON");
  sub->callback([o] { run(*o); });
});

}  // namespace
