// The CUDA rasterizer against the CPU one (the reference) and against finite differences of the
// CPU's double path. Every test that needs a GPU skips, saying why, where this build has no
// CUDA backend or the machine no device (CI); the floors are in docs/rasterizer_cuda.md.
#include "raster_cuda/rasterizer_cuda.hpp"
#include "raster_cuda/need_gpu.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "raster/avatar_cloud.hpp"
#include "raster/raster_scene.hpp"

namespace ks {
namespace {

double psnr_of(const std::vector<float>& a, const std::vector<float>& b) {
  double se = 0;
  for (size_t i = 0; i < a.size(); ++i) se += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  const double mse = se / double(std::max<size_t>(1, a.size()));
  return mse <= 0 ? 200.0 : 10 * std::log10(1.0 / mse);
}

// |a - b| / |b| over a whole array.
double rel_error(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    den += double(b[i]) * b[i];
  }
  return std::sqrt(num / std::max(den, 1e-30));
}

TEST(RasterCuda, WithoutTheBackendEveryEntryPointSaysSo) {
  if (cuda::raster_cuda_compiled()) GTEST_SKIP() << "this build has the CUDA backend";
  EXPECT_EQ(cuda::raster_cuda_devices(), 0);
  try {
    cuda::RasterizerCuda r;
    FAIL() << "constructed without CUDA";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("KS_CUDA"), std::string::npos) << e.what();
  }
}

TEST(RasterCuda, ForwardMatchesTheCpu) {
  KS_NEED_GPU();
  for (int deg : {0, 3}) {
    Gaussians g = make_avatar_cloud(30000, 3);
    if (deg == 0) {
      Gaussians g0 = g;
      g0.sh_degree = 0;
      g0.sh.assign(g.size() * 3, 0.f);
      for (size_t i = 0; i < g.size(); ++i)
        for (int c = 0; c < 3; ++c) g0.sh[3 * i + c] = g.sh[i * 16 * 3 + c];
      g = g0;
    }
    const Camera cam = avatar_camera(320, 480);
    RasterSettings s;
    s.background[0] = 0.2f, s.background[1] = 0.5f, s.background[2] = 0.9f;
    s.depth = true;
    RasterResult cpu, gpu;
    rasterize_forward(g, cam, s, cpu);
    cuda::RasterizerCuda r;
    r.upload(g);
    r.forward(cam, s);
    r.download(gpu);
    ASSERT_EQ(gpu.color.data.size(), cpu.color.data.size());
    const double pc = psnr_of(gpu.color.data, cpu.color.data);
    const double pa = psnr_of(gpu.alpha.data, cpu.alpha.data);
    RecordProperty("color_psnr_deg" + std::to_string(deg), std::to_string(pc));
    std::printf("degree %d: colour PSNR %.2f dB, alpha PSNR %.2f dB, depth rel. error %.2e\n", deg,
                pc, pa, rel_error(gpu.depth.data, cpu.depth.data));
    EXPECT_GE(pc, 50.0);
    EXPECT_GE(pa, 50.0);
    EXPECT_LE(rel_error(gpu.depth.data, cpu.depth.data), 1e-3);
    size_t same = 0, visible = 0;
    for (size_t i = 0; i < g.size(); ++i) {
      same += gpu.radii[i] == cpu.radii[i];
      visible += cpu.radii[i] > 0;
    }
    EXPECT_GT(visible, g.size() / 2);
    EXPECT_GE(double(same), 0.999 * double(g.size()));
    // The image-only forward gives the same colour, and no backward follows it.
    RasterSettings io = s;
    io.image_only = true;
    io.depth = false;
    RasterResult img;
    r.forward(cam, io);
    r.download(img);
    EXPECT_EQ(img.color.data, gpu.color.data);
    EXPECT_TRUE(img.depth.empty());
    Image dc(cam.width, cam.height, 3), da;
    EXPECT_THROW(r.backward(dc, da), Error);
  }
}

TEST(RasterCuda, GradientsMatchTheCpu) {
  KS_NEED_GPU();
  test::SceneOptions o;
  o.n = 3000;
  o.sh_degree = 3;
  o.scale_min = 0.005, o.scale_max = 0.04;
  const Gaussians g = test::random_scene(o, 11);
  const Camera cam = test::test_camera(160, 120);
  RasterSettings s;
  s.background[0] = 0.3f, s.background[1] = 0.1f, s.background[2] = 0.7f;
  Image dc(cam.width, cam.height, 3), da(cam.width, cam.height, 1);
  test::random_upstream(dc, da, 5);
  RasterResult cpu;
  RasterGrads gc, gg;
  rasterize_forward(g, cam, s, cpu);
  rasterize_backward(g, cam, s, cpu, dc, da, gc);
  cuda::RasterizerCuda r;
  r.upload(g);
  r.forward(cam, s);
  r.backward(dc, da);
  r.download_grads(gg);
  const struct {
    const char* name;
    const std::vector<float>& gpu;
    const std::vector<float>& cpu;
  } arrays[] = {
      {"means", gg.means, gc.means}, {"log_scales", gg.log_scales, gc.log_scales},
      {"quats", gg.quats, gc.quats}, {"opacity_logits", gg.opacity_logits, gc.opacity_logits},
      {"sh", gg.sh, gc.sh},          {"means2d", gg.means2d, gc.means2d}};
  for (const auto& a : arrays) {
    ASSERT_EQ(a.gpu.size(), a.cpu.size()) << a.name;
    const double e = rel_error(a.gpu, a.cpu);
    std::printf("%-15s relative error %.2e\n", a.name, e);
    EXPECT_LE(e, 1e-3) << a.name;
  }
}

// The GPU's gradients of L = sum(wc * colour) + sum(wa * alpha) against central differences
// of L through the CPU's double forward, on a small scene as the CPU's own gradient tests use
// (few Gaussians well inside the image, moderate opacities: no 0.99 clamp, no early stop).
TEST(RasterCuda, GradientsMatchFiniteDifferencesOfTheDoublePath) {
  KS_NEED_GPU();
  test::SceneOptions o;
  o.n = 5;
  o.sh_degree = 3;
  o.spread = 0.12;
  o.scale_min = 0.03, o.scale_max = 0.07;
  o.opacity_min = 0.3, o.opacity_max = 0.8;
  const Gaussians g = test::random_scene(o, 22);
  const Camera cam = test::test_camera(32, 32, 0.56, 0.41);
  RasterSettings s;
  s.background[0] = 0.2f, s.background[1] = 0.6f, s.background[2] = 0.4f;
  Image wc(cam.width, cam.height, 3), wa(cam.width, cam.height, 1);
  test::random_upstream(wc, wa, 9);
  cuda::RasterizerCuda r;
  r.upload(g);
  r.forward(cam, s);
  r.backward(wc, wa);
  RasterGrads gg;
  r.download_grads(gg);
  auto loss = [&](const GaussiansD& gd) {
    RasterResultD out;
    rasterize_forward(gd, cam, s, out);
    double l = 0;
    for (size_t i = 0; i < out.color.data.size(); ++i) l += wc.data[i] * out.color.data[i];
    for (size_t i = 0; i < out.alpha.data.size(); ++i) l += wa.data[i] * out.alpha.data[i];
    return l;
  };
  const GaussiansD base = GaussiansD::from(g);
  const double h = 1e-5;
  int checked = 0;
  auto check_array = [&](const char* name, std::vector<double> GaussiansD::*field,
                         const std::vector<float>& analytic) {
    for (size_t k = 0; k < analytic.size(); ++k) {
      GaussiansD p = base, m = base;
      (p.*field)[k] += h;
      (m.*field)[k] -= h;
      const double fd = (loss(p) - loss(m)) / (2 * h);
      EXPECT_NEAR(analytic[k], fd, 1e-4 + 2e-3 * std::abs(fd)) << name << "[" << k << "]";
      ++checked;
    }
  };
  check_array("means", &GaussiansD::means, gg.means);
  check_array("log_scales", &GaussiansD::log_scales, gg.log_scales);
  check_array("quats", &GaussiansD::quats, gg.quats);
  check_array("opacity_logits", &GaussiansD::opacity_logits, gg.opacity_logits);
  check_array("sh", &GaussiansD::sh, gg.sh);
  EXPECT_EQ(checked, 5 * (3 + 3 + 4 + 1 + 16 * 3));
}

// Playback's upload: new means, rotations and opacities with the last upload's scales and SH
// render as a whole upload of the same Gaussians does.
// The images alone (playback's frames), into a result whose buffers have the right size
// already; and the Gaussians back as uploaded.
TEST(RasterCuda, ImagesAloneAndGaussiansDownload) {
  KS_NEED_GPU();
  const Gaussians g = make_avatar_cloud(5000, 2);
  const Camera cam = avatar_camera(128, 192);
  cuda::RasterizerCuda r;
  r.upload(g);
  r.forward(cam, RasterSettings{});
  RasterResult full, images;
  r.download(full);
  EXPECT_EQ(full.radii.size(), g.size());
  EXPECT_EQ(full.depths.size(), g.size());
  for (int round = 0; round < 2; ++round) {
    r.download(images, false);
    EXPECT_EQ(images.color.data, full.color.data);
    EXPECT_EQ(images.alpha.data, full.alpha.data);
    EXPECT_TRUE(images.radii.empty() && images.depths.empty());
  }
  Gaussians back;
  r.download_gaussians(back);
  EXPECT_EQ(back.sh_degree, g.sh_degree);
  EXPECT_EQ(back.means, g.means);
  EXPECT_EQ(back.log_scales, g.log_scales);
  EXPECT_EQ(back.quats, g.quats);
  EXPECT_EQ(back.opacity_logits, g.opacity_logits);
  EXPECT_EQ(back.sh, g.sh);
}

TEST(RasterCuda, BadInputsAreRefused) {
  KS_NEED_GPU();
  cuda::RasterizerCuda r;
  Gaussians g = make_avatar_cloud(100, 1);
  RasterResult out;
  EXPECT_THROW(r.download(out), Error);  // nothing rendered yet
  Gaussians bad = g;
  bad.means.pop_back();
  EXPECT_THROW(r.upload(bad), Error);
  r.upload(g);
  const Camera cam = avatar_camera(64, 96);
  r.forward(cam, RasterSettings{});
  EXPECT_THROW(r.backward(Image(32, 96, 3), Image()), Error);
  EXPECT_THROW(r.backward(Image(64, 96, 3), Image(64, 96, 3)), Error);
  RasterGrads gr;
  EXPECT_THROW(r.download_grads(gr), Error);
  // An empty set renders the background.
  Gaussians none;
  none.sh_degree = 0;
  r.upload(none);
  RasterSettings s;
  s.background[1] = 1.f;
  r.forward(cam, s);
  r.download(out);
  for (size_t p = 0; p < out.alpha.data.size(); ++p) {
    ASSERT_EQ(out.alpha.data[p], 0.f);
    ASSERT_EQ(out.color.data[3 * p + 1], 1.f);
  }
}

}  // namespace
}  // namespace ks
