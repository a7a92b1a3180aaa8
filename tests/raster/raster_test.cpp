#include "raster/rasterizer.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <utility>

#include "core/error.hpp"
#include "raster/raster_scene.hpp"

namespace ks {
namespace {

using test::random_scene;
using test::reference_render;
using test::SceneOptions;
using test::test_camera;

void expect_matches_reference(const Gaussians& g, const Camera& cam,
                              const RasterSettings& settings) {
  RasterSettings s = settings;
  s.depth = true;
  RasterResult r;
  rasterize_forward(g, cam, s, r);
  const auto ref = reference_render(g, cam, s);
  const double p_col = test::psnr(ref.color, r.color.data);
  const double p_alpha = test::psnr(ref.alpha, r.alpha.data);
  EXPECT_GE(p_col, 35.0);
  EXPECT_GE(p_alpha, 35.0);
  // In practice the float tile renderer is near-exact against the double reference.
  EXPECT_GE(p_col, 60.0) << "colour PSNR " << p_col;
  double max_depth_err = 0;
  for (size_t i = 0; i < ref.depth.size(); ++i)
    max_depth_err = std::max(max_depth_err, std::abs(ref.depth[i] - r.depth.data[i]));
  EXPECT_LT(max_depth_err, 1e-3);
  // The double instantiation of the same code agrees to rounding.
  RasterResultD rd;
  rasterize_forward(GaussiansD::from(g), cam, s, rd);
  double max_err = 0;
  for (size_t i = 0; i < ref.color.size(); ++i)
    max_err = std::max(max_err, std::abs(ref.color[i] - rd.color.data[i]));
  EXPECT_LT(max_err, 1e-9);
}

TEST(Raster, ForwardMatchesReferenceSH0) {
  SceneOptions o;
  o.n = 60;
  RasterSettings s;
  s.background[0] = 0.2f, s.background[1] = 0.5f, s.background[2] = 0.9f;
  for (unsigned seed = 1; seed <= 3; ++seed)
    expect_matches_reference(random_scene(o, seed), test_camera(45, 70, 0.3, 0.62), s);
}

TEST(Raster, ForwardMatchesReferenceSH3) {
  SceneOptions o;
  o.n = 80;
  o.sh_degree = 3;
  o.opacity_max = 0.999;  // exercises the 0.99 clamp and early termination
  RasterSettings s;
  s.background[1] = 1.0f;
  for (unsigned seed = 10; seed <= 12; ++seed)
    expect_matches_reference(random_scene(o, seed), test_camera(67, 50, 0.61, 0.35), s);
}

// Enough Gaussians for the threaded paths of the depth sort and of the visible ones' compaction
// (above 20,000), a third of them culled (behind the camera, or too transparent), on 1 and 2
// threads: the same image, and the reference's.
TEST(Raster, ManyGaussiansWithCulledOnesMatchTheReference) {
  SceneOptions o;
  o.n = 24000;
  o.scale_min = 0.004, o.scale_max = 0.012;
  o.opacity_min = 0.05, o.opacity_max = 0.5;
  Gaussians g = random_scene(o, 41);
  for (size_t i = 0; i < g.size(); i += 3) {
    if (i % 2)
      g.means[3 * i + 2] = 3.0f;  // behind the camera (at z = 2 looking at -z)
    else
      g.opacity_logits[i] = -8.f;  // opacity below 1 / 255
  }
  const Camera cam = test_camera(40, 30, 0.5, 0.5);
  RasterSettings s;
  s.background[2] = 0.4f;
  const int saved = omp_get_max_threads();
  RasterResult r1, r2;
  omp_set_num_threads(1);
  rasterize_forward(g, cam, s, r1);
  omp_set_num_threads(2);
  rasterize_forward(g, cam, s, r2);
  // Image only (tile lists of ids, the records not copied) on 2 and 3 threads, twice each (the
  // buffers swapped by the first call serve the second).
  RasterSettings si = s;
  si.image_only = true;
  for (const int threads : {2, 3}) {
    omp_set_num_threads(threads);
    RasterResult r3;
    rasterize_forward(g, cam, si, r3);
    rasterize_forward(g, cam, si, r3);
    EXPECT_EQ(r3.color.data, r1.color.data) << threads << " threads";
  }
  omp_set_num_threads(saved);
  EXPECT_EQ(r1.color.data, r2.color.data);
  EXPECT_EQ(r1.n_contrib, r2.n_contrib);
  const auto ref = reference_render(g, cam, s);
  EXPECT_GE(test::psnr(ref.color, r2.color.data), 60.0);
  EXPECT_GE(test::psnr(ref.alpha, r2.alpha.data), 60.0);
}

// The tile lists come out in depth order (ties by id) whatever the depths' span: within a few
// hundred units in the last place (the sort's top stage alone), a few thousand (one pass within
// its buckets), a factor of two (two) and from 5 cm to hundreds of metres (three), on one thread
// and, with more than 20,000 visible, on two and three (the buckets shared among them).
TEST(Raster, TileListsAreInDepthOrder) {
  struct Span {
    double near, far;
  };
  const int saved = omp_get_max_threads();
  for (const int n : {500, 24000})
    for (const Span span :
         {Span{1.0, 1.00001}, Span{1.0, 1.0001}, Span{1.0, 1.9}, Span{0.05, 400.0}})
      for (const int threads : {1, 2, 3}) {
        if (n < 20000 && threads > 1) continue;  // one thread sorts so few
        omp_set_num_threads(threads);
        SceneOptions o;
        o.n = n;
        o.scale_min = 0.002, o.scale_max = 0.01;
        Gaussians g = random_scene(o, 7);
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> U(0.0, 1.0);
        // The camera looks from z = 2 towards the origin: a mean at z = 2 - d lies about d away;
        // x and y scaled with d keep it in view. Every 50th is a copy of the first (equal depths).
        for (size_t i = 0; i < g.size(); ++i) {
          if (i % 50 == 0) {
            for (int c = 0; c < 3; ++c) g.means[3 * i + c] = g.means[size_t(c)];
            continue;
          }
          const double d = span.near + (span.far - span.near) * U(rng);
          g.means[3 * i] = float(g.means[3 * i] * d / 2), g.means[3 * i + 1] *= float(d / 2);
          g.means[3 * i + 2] = float(2.0 - d);
        }
        const Camera cam = test_camera(64, 48, 0.5, 0.5);
        RasterResult r;
        rasterize_forward(g, cam, {}, r);
        size_t checked = 0, ties = 0;
        for (size_t t = 0; t < r.tile_ranges.size() / 2; ++t)
          for (uint32_t e = r.tile_ranges[2 * t] + 1; e < r.tile_ranges[2 * t + 1]; ++e) {
            const uint32_t a = r.point_list[e - 1], b = r.point_list[e];
            const float za = r.packed[16 * size_t(a) + 9], zb = r.packed[16 * size_t(b) + 9];
            ASSERT_TRUE(za < zb || (za == zb && a < b))
                << n << " " << span.far << " threads " << threads << " tile " << t;
            ++checked;
            ties += za == zb;
          }
        EXPECT_GT(checked, size_t(n) / 10) << n << " " << span.far;
        EXPECT_GT(ties, 0u) << n << " " << span.far;
      }
  omp_set_num_threads(saved);
}

TEST(Raster, ForwardIsDeterministicAndReusesBuffers) {
  SceneOptions o;
  o.n = 200;
  o.sh_degree = 1;
  const Gaussians g = random_scene(o, 5);
  const Camera cam = test_camera(70, 90);
  RasterResult a, b;
  rasterize_forward(g, cam, {}, a);
  const float* ptr = a.color.data.data();
  rasterize_forward(g, cam, {}, a);
  rasterize_forward(g, cam, {}, b);
  EXPECT_EQ(ptr, a.color.data.data());
  EXPECT_EQ(a.color.data, b.color.data);
  EXPECT_EQ(a.point_list, b.point_list);
}

TEST(Raster, CullsBehindCameraAndReportsScreenData) {
  Gaussians g;
  g.resize(2);
  g.means = {0, 0, 0, 0, 0, 5};  // second one is behind the camera (camera at z = 2)
  for (float& l : g.log_scales) l = std::log(0.05f);
  const Camera cam = test_camera(32, 32, 0.5, 0.5);
  RasterResult r;
  rasterize_forward(g, cam, {}, r);
  EXPECT_GT(r.radii[0], 0);
  EXPECT_EQ(r.radii[1], 0);
  const auto uv = cam.project({0, 0, 0});
  EXPECT_NEAR(r.packed[0], uv.x(), 1e-4);  // the render record's 2D mean
  EXPECT_NEAR(r.packed[1], uv.y(), 1e-4);
}

// A point at (u, v) lies in pixel (floor(u), floor(v)): a tiny Gaussian lights that pixel.
TEST(Raster, PixelCentreConvention) {
  Gaussians g;
  g.resize(1);
  Camera cam = test_camera(16, 16, 0.5, 0.5);
  cam.R.setIdentity();
  cam.t.setZero();
  cam.cx = 5.3, cam.cy = 9.7;
  g.means = {0, 0, 1};
  for (float& l : g.log_scales) l = std::log(1e-5f);
  g.opacity_logits[0] = 5;
  RasterResult r;
  rasterize_forward(g, cam, {}, r);
  int best = -1;
  float bestv = -1;
  for (int i = 0; i < 256; ++i)
    if (r.alpha.data[i] > bestv) bestv = r.alpha.data[i], best = i;
  EXPECT_EQ(best % 16, 5);
  EXPECT_EQ(best / 16, 9);
}

// The wider kernels (AVX2, AVX-512) against the baseline (SSE2) in one process, on scenes with the
// 0.99 clamp, early termination, tiny and large Gaussians, and an image whose edges cut tiles:
// the same images and gradients up to rounding (the wider kernels fuse multiply-adds, rounded
// once where the baseline rounds the product and then the sum, and sum in another order). A
// pixel whose last contributor differs (an alpha or a transmittance that a rounding moves across
// its threshold) may differ by one Gaussian's share: at most a few such pixels.
void expect_kernel_agrees(RasterKernel kernel, unsigned seed, double scale_min, double scale_max,
                          int w, int h) {
  SceneOptions o;
  o.n = 300;
  o.sh_degree = 3;
  o.opacity_max = 0.999;
  o.scale_min = scale_min, o.scale_max = scale_max;
  const Gaussians g = random_scene(o, seed);
  const Camera cam = test_camera(w, h, 0.45, 0.55);
  RasterSettings s;
  s.background[0] = 0.3f;
  s.depth = true;
  RasterResult r[2];
  RasterGrads gr[2];
  Image dc(cam.width, cam.height, 3), da(cam.width, cam.height, 1);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  for (float& v : dc.data) v = U(rng);
  for (float& v : da.data) v = U(rng);
  for (int k = 0; k < 2; ++k) {
    s.kernel = k == 0 ? RasterKernel::kBaseline : kernel;
    rasterize_forward(g, cam, s, r[k]);
    rasterize_backward(g, cam, s, r[k], dc, da, gr[k]);
  }
  const size_t npix = size_t(w) * h;
  size_t moved = 0;
  for (size_t p = 0; p < npix; ++p) {
    if (r[0].n_contrib[p] != r[1].n_contrib[p]) {
      ++moved;
      continue;
    }
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(r[0].color.data[3 * p + c], r[1].color.data[3 * p + c], 1e-5f) << p;
    EXPECT_NEAR(r[0].alpha.data[p], r[1].alpha.data[p], 1e-5f) << p;
    EXPECT_NEAR(r[0].final_T[p], r[1].final_T[p], 1e-5f) << p;
    EXPECT_NEAR(r[0].depth.data[p], r[1].depth.data[p], 1e-5f * (1 + r[0].depth.data[p])) << p;
  }
  EXPECT_LE(moved, npix / 1000);
  auto close = [](const std::vector<float>& a, const std::vector<float>& b, const char* name) {
    ASSERT_EQ(a.size(), b.size()) << name;
    float scale = 0;
    for (float v : a) scale = std::max(scale, std::abs(v));
    ASSERT_GT(scale, 0.f) << name;
    for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-5f * scale) << name << i;
  };
  close(gr[0].means, gr[1].means, "means");
  close(gr[0].log_scales, gr[1].log_scales, "log_scales");
  close(gr[0].quats, gr[1].quats, "quats");
  close(gr[0].opacity_logits, gr[1].opacity_logits, "opacity_logits");
  close(gr[0].sh, gr[1].sh, "sh");
}

// The forward's record of where each entry contributed (entry_cells, 4 x 2-pixel cells) holds
// every contribution: the backward through it gives the gradients it gives when every cell is
// marked (then it visits each entry's whole box). And it marks only cells where a pixel's last
// contributor lies at or beyond the entry, so it skips work: fewer cells than the boxes hold.
// Returns the most entries a tile has, and how many entries lie beyond their tile's last
// contributor (the forward stopped before them).
std::pair<size_t, size_t> expect_cells_hold_contributions(const Gaussians& g, const Camera& cam) {
  Image dc(cam.width, cam.height, 3), da(cam.width, cam.height, 1);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  for (float& v : dc.data) v = U(rng);
  for (float& v : da.data) v = U(rng);
  const int tiles_x = (cam.width + kTileSize - 1) / kTileSize;
  size_t most = 0, beyond = 0;
  std::vector<RasterKernel> kernels = {RasterKernel::kBaseline};
  if (raster_avx2_available()) kernels.push_back(RasterKernel::kAvx2);
  if (raster_avx512_available()) kernels.push_back(RasterKernel::kAvx512);
  std::vector<std::vector<uint32_t>> recorded;
  for (const RasterKernel k : kernels) {
    SCOPED_TRACE(int(k));
    RasterSettings s;
    s.kernel = k;
    RasterResult r;
    r.entry_cells.assign(1 << 20, ~0u);  // stale cells of a reused result: all overwritten
    rasterize_forward(g, cam, s, r);
    EXPECT_EQ(r.entry_cells.size(), r.point_list.size());
    if (r.entry_cells.size() != r.point_list.size()) break;
    size_t marked = 0, empty = 0;
    for (size_t t = 0; t < r.tile_ranges.size() / 2; ++t) {
      const int ox = int(t % tiles_x) * kTileSize, oy = int(t / tiles_x) * kTileSize;
      most = std::max<size_t>(most, r.tile_ranges[2 * t + 1] - r.tile_ranges[2 * t]);
      uint32_t jmax = 0;  // one past the tile's last contributor
      for (int y = oy; y < std::min(oy + kTileSize, cam.height); ++y)
        for (int x = ox; x < std::min(ox + kTileSize, cam.width); ++x)
          jmax = std::max(jmax, r.n_contrib[size_t(y) * cam.width + x]);
      for (uint32_t e = r.tile_ranges[2 * t]; e < r.tile_ranges[2 * t + 1]; ++e) {
        const uint32_t j = e - r.tile_ranges[2 * t], cells = r.entry_cells[e];
        empty += cells == 0;
        if (j >= jmax) {
          ++beyond;
          EXPECT_EQ(cells, 0u) << "tile " << t << " entry " << j;
        }
        for (int cell = 0; cell < 32; ++cell) {
          if (!(cells >> cell & 1)) continue;
          ++marked;
          bool reached = false;  // a pixel of the cell whose last contributor is j or later
          for (int y = oy + cell / 4 * 2; y < oy + cell / 4 * 2 + 2 && y < cam.height; ++y)
            for (int x = ox + cell % 4 * 4; x < ox + cell % 4 * 4 + 4 && x < cam.width; ++x)
              reached |= r.n_contrib[size_t(y) * cam.width + x] > j;
          EXPECT_TRUE(reached) << "tile " << t << " entry " << j << " cell " << cell;
        }
      }
    }
    EXPECT_GT(marked, 0u);
    EXPECT_GT(empty, 0u);  // entries that took no pixel at all
    recorded.push_back(r.entry_cells);
    // One thread: the tiles' sums then come in one order (with two, in the order the threads
    // happen to take the tiles).
    RasterGrads exact, all;
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    rasterize_backward(g, cam, s, r, dc, da, exact);
    std::fill(r.entry_cells.begin(), r.entry_cells.end(), ~0u);
    rasterize_backward(g, cam, s, r, dc, da, all);
    omp_set_num_threads(threads);
    EXPECT_EQ(exact.means, all.means);
    EXPECT_EQ(exact.log_scales, all.log_scales);
    EXPECT_EQ(exact.quats, all.quats);
    EXPECT_EQ(exact.opacity_logits, all.opacity_logits);
    EXPECT_EQ(exact.sh, all.sh);
    EXPECT_EQ(exact.means2d, all.means2d);
  }
  // The AVX2 kernel's blocks are the cells; the AVX-512 kernel's rows give the same cells.
  if (kernels.size() == 3) {
    EXPECT_EQ(recorded[1], recorded[2]);
  }
  return {most, beyond};
}

TEST(Raster, EntryCellsHoldEveryContribution) {
  SceneOptions o;
  o.n = 300;
  o.sh_degree = 1;
  o.opacity_max = 0.999;
  o.scale_min = 0.01, o.scale_max = 0.1;
  expect_cells_hold_contributions(random_scene(o, 41), test_camera(83, 61, 0.45, 0.55));
  // Tiles with more entries than the forward gathers at a time (252): pixels that take
  // Gaussians through several batches, and (opaque) pixels that finish within the first one,
  // the rest of the list left untouched.
  SceneOptions deep;
  deep.n = 4000;
  deep.scale_min = 0.01, deep.scale_max = 0.04;
  deep.opacity_min = 0.2, deep.opacity_max = 0.7;
  EXPECT_GT(expect_cells_hold_contributions(random_scene(deep, 43), test_camera(48, 40)).first,
            252u);
  SceneOptions opaque;
  opaque.n = 3000;
  opaque.scale_min = 0.05, opaque.scale_max = 0.2;
  opaque.opacity_min = 0.5, opaque.opacity_max = 0.99;
  opaque.spread = 1.0;
  const auto [most, beyond] =
      expect_cells_hold_contributions(random_scene(opaque, 43), test_camera(48, 40));
  EXPECT_GT(most, 252u);
  EXPECT_GT(beyond, 252u);
}

// Kernels by name (the bench's --kernel) and the name of the one a setting runs.
TEST(Raster, KernelsByName) {
  EXPECT_EQ(raster_kernel_from_name("auto"), RasterKernel::kAuto);
  EXPECT_EQ(raster_kernel_from_name("baseline"), RasterKernel::kBaseline);
  EXPECT_EQ(raster_kernel_from_name("avx2"), RasterKernel::kAvx2);
  EXPECT_EQ(raster_kernel_from_name("avx512"), RasterKernel::kAvx512);
  EXPECT_THROW(raster_kernel_from_name("sse9"), Error);
  RasterSettings s;
  s.kernel = RasterKernel::kBaseline;
  EXPECT_STREQ(raster_kernel_name(s), "baseline");
}

// The render records (also the backward's per-Gaussian state) of the visible Gaussians.
template <class T>
std::vector<T> visible_records(const RasterResultT<T>& r) {
  std::vector<T> out;
  for (size_t i = 0; i < r.radii.size(); ++i)
    if (r.radii[i] > 0) out.insert(out.end(), &r.packed[16 * i], &r.packed[16 * i] + 16);
  return out;
}

// 300 Gaussians of SH degree 3, some nearly opaque (pixels finish early).
Gaussians opaque_sh3_scene(unsigned seed) {
  SceneOptions o;
  o.n = 300;
  o.sh_degree = 3;
  o.opacity_max = 0.999;
  return random_scene(o, seed);
}

TEST(Raster, ImageOnlyGivesTheSameImageWithoutBackwardState) {
  const Gaussians g = opaque_sh3_scene(31);
  const Camera cam = test_camera(70, 90, 0.45, 0.55);
  for (const RasterKernel k : {RasterKernel::kBaseline, RasterKernel::kAuto}) {
    RasterSettings s;
    s.kernel = k;
    s.depth = true;
    RasterResult full, img;
    rasterize_forward(g, cam, s, full);
    s.image_only = true;
    s.depth = false;
    rasterize_forward(g, cam, s, img);
    EXPECT_EQ(img.color.data, full.color.data);
    EXPECT_EQ(img.alpha.data, full.alpha.data);
    EXPECT_TRUE(img.depth.data.empty());
    EXPECT_TRUE(img.final_T.empty());
    EXPECT_TRUE(img.n_contrib.empty());
    EXPECT_TRUE(img.entry_cells.empty());
    EXPECT_EQ(img.radii, full.radii);
    EXPECT_EQ(img.depths, full.depths);
    EXPECT_EQ(visible_records(img), visible_records(full));
    Image dc(cam.width, cam.height, 3);
    RasterGrads gr;
    EXPECT_THROW(rasterize_backward(g, cam, s, img, dc, Image(), gr), Error);
    // The same buffers serve a full forward again.
    s.image_only = false;
    s.depth = true;
    rasterize_forward(g, cam, s, img);
    EXPECT_EQ(img.depth.data, full.depth.data);
    EXPECT_EQ(img.n_contrib, full.n_contrib);
    EXPECT_EQ(img.entry_cells, full.entry_cells);
    EXPECT_EQ(visible_records(img), visible_records(full));
  }
  // The double path alike.
  const GaussiansD gd = GaussiansD::from(g);
  RasterSettings s;
  RasterResultD full, img;
  rasterize_forward(gd, cam, s, full);
  s.image_only = true;
  rasterize_forward(gd, cam, s, img);
  EXPECT_EQ(img.color.data, full.color.data);
  EXPECT_EQ(img.radii, full.radii);
  EXPECT_EQ(visible_records(img), visible_records(full));
}

// The expected depth is made only when asked for, and asking changes nothing else: the same
// images, backward state and gradients without it; the same depth with image_only. (One thread:
// with more, the threads' gradient accumulators take the tiles in whatever order the schedule
// gives them, so two backward passes can differ in the last bits.)
TEST(Raster, DepthOnlyWhenAskedFor) {
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const Gaussians g = opaque_sh3_scene(37);
  const Camera cam = test_camera(70, 90, 0.45, 0.55);
  Image dc(cam.width, cam.height, 3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-1.f, 1.f);
  for (float& v : dc.data) v = U(rng);
  for (const RasterKernel k : {RasterKernel::kBaseline, RasterKernel::kAuto}) {
    RasterSettings s;
    s.kernel = k;
    s.depth = true;
    RasterResult with, without, img;
    RasterGrads gw, gwo;
    rasterize_forward(g, cam, s, with);
    rasterize_backward(g, cam, s, with, dc, Image(), gw);
    ASSERT_EQ(with.depth.data.size(), size_t(cam.width) * cam.height);
    EXPECT_GT(*std::max_element(with.depth.data.begin(), with.depth.data.end()), 0.f);
    s.depth = false;
    rasterize_forward(g, cam, s, without);
    rasterize_backward(g, cam, s, without, dc, Image(), gwo);
    EXPECT_TRUE(without.depth.data.empty());
    EXPECT_EQ(without.color.data, with.color.data);
    EXPECT_EQ(without.alpha.data, with.alpha.data);
    EXPECT_EQ(without.final_T, with.final_T);
    EXPECT_EQ(without.n_contrib, with.n_contrib);
    EXPECT_EQ(without.entry_cells, with.entry_cells);
    EXPECT_EQ(gwo.means, gw.means);
    EXPECT_EQ(gwo.sh, gw.sh);
    EXPECT_EQ(gwo.opacity_logits, gw.opacity_logits);
    s.image_only = true;
    s.depth = true;
    rasterize_forward(g, cam, s, img);
    EXPECT_EQ(img.depth.data, with.depth.data);
    EXPECT_EQ(img.color.data, with.color.data);
  }
  const GaussiansD gd = GaussiansD::from(g);
  RasterSettings s;
  RasterResultD with, without;
  s.depth = true;
  rasterize_forward(gd, cam, s, with);
  s.depth = false;
  rasterize_forward(gd, cam, s, without);
  EXPECT_EQ(with.depth.data.size(), size_t(cam.width) * cam.height);
  EXPECT_TRUE(without.depth.data.empty());
  EXPECT_EQ(without.color.data, with.color.data);
  EXPECT_EQ(without.n_contrib, with.n_contrib);
  omp_set_num_threads(saved);
}

TEST(Raster, BaselineAndAvx2KernelsAgree) {
  if (!raster_avx2_available()) GTEST_SKIP() << "this CPU has no AVX2 and FMA";
  expect_kernel_agrees(RasterKernel::kAvx2, 21, 0.02, 0.08, 83, 61);
  expect_kernel_agrees(RasterKernel::kAvx2, 22, 0.002, 0.3, 97, 130);
}

TEST(Raster, BaselineAndAvx512KernelsAgree) {
  if (!raster_avx512_available()) GTEST_SKIP() << "this CPU has no AVX-512";
  expect_kernel_agrees(RasterKernel::kAvx512, 21, 0.02, 0.08, 83, 61);
  expect_kernel_agrees(RasterKernel::kAvx512, 22, 0.002, 0.3, 97, 130);
  expect_kernel_agrees(RasterKernel::kAvx512, 23, 0.01, 0.05, 200, 150);
}

// The AVX-512 kernels are the AVX2 kernels' code compiled for AVX-512VL: every output of the
// forward (image-only and full) and every gradient the same bits (on one thread: with more, the
// threads' accumulators take the tiles in whatever order the schedule gives them).
TEST(Raster, Avx512KernelsGiveTheAvx2Bits) {
  if (!raster_avx512_available()) GTEST_SKIP() << "this CPU has no AVX-512";
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  for (const unsigned seed : {24u, 25u}) {
    SCOPED_TRACE(seed);
    SceneOptions o;
    o.n = 400;
    o.sh_degree = 3;
    o.opacity_max = 0.999;
    o.scale_min = 0.005, o.scale_max = seed == 24u ? 0.05 : 0.3;
    const Gaussians g = random_scene(o, seed);
    const Camera cam = test_camera(131, 97, 0.45, 0.55);
    Image dc(cam.width, cam.height, 3), da(cam.width, cam.height, 1);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> U(-1.f, 1.f);
    for (float& v : dc.data) v = U(rng);
    for (float& v : da.data) v = U(rng);
    RasterResult r[2], img[2];
    RasterGrads gr[2];
    for (int k = 0; k < 2; ++k) {
      RasterSettings s;
      s.background[1] = 0.4f;
      s.depth = true;
      s.kernel = k == 0 ? RasterKernel::kAvx2 : RasterKernel::kAvx512;
      rasterize_forward(g, cam, s, r[k]);
      rasterize_backward(g, cam, s, r[k], dc, da, gr[k]);
      s.image_only = true;
      rasterize_forward(g, cam, s, img[k]);
    }
    EXPECT_EQ(r[0].color.data, r[1].color.data);
    EXPECT_EQ(r[0].alpha.data, r[1].alpha.data);
    EXPECT_EQ(r[0].depth.data, r[1].depth.data);
    EXPECT_EQ(r[0].final_T, r[1].final_T);
    EXPECT_EQ(r[0].n_contrib, r[1].n_contrib);
    EXPECT_EQ(r[0].entry_cells, r[1].entry_cells);
    EXPECT_EQ(img[0].color.data, img[1].color.data);
    EXPECT_EQ(img[0].alpha.data, img[1].alpha.data);
    EXPECT_EQ(gr[0].means, gr[1].means);
    EXPECT_EQ(gr[0].log_scales, gr[1].log_scales);
    EXPECT_EQ(gr[0].quats, gr[1].quats);
    EXPECT_EQ(gr[0].opacity_logits, gr[1].opacity_logits);
    EXPECT_EQ(gr[0].sh, gr[1].sh);
    EXPECT_EQ(gr[0].means2d, gr[1].means2d);
  }
  omp_set_num_threads(saved);
}

// ---- gradients -----------------------------------------------------------------------------

struct Loss {
  ImageD wc, wa;
  double operator()(const RasterResultD& r) const {
    double l = 0;
    for (size_t i = 0; i < wc.data.size(); ++i) l += wc.data[i] * r.color.data[i];
    for (size_t i = 0; i < wa.data.size(); ++i) l += wa.data[i] * r.alpha.data[i];
    return l;
  }
};

Loss random_loss(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  Loss L;
  L.wc = ImageD(w, h, 3);
  L.wa = ImageD(w, h, 1);
  for (double& v : L.wc.data) v = U(rng);
  for (double& v : L.wa.data) v = U(rng);
  return L;
}

void check_group(const char* name, std::vector<double>& param, const std::vector<double>& grad,
                 const std::function<double()>& eval) {
  ASSERT_EQ(param.size(), grad.size()) << name;
  const double eps = 1e-6;
  double max_abs = 0;
  for (double gv : grad) max_abs = std::max(max_abs, std::abs(gv));
  EXPECT_GT(max_abs, 1e-6) << name << ": all gradients are zero";
  for (size_t i = 0; i < param.size(); ++i) {
    const double keep = param[i];
    param[i] = keep + eps;
    const double lp = eval();
    param[i] = keep - eps;
    const double lm = eval();
    param[i] = keep;
    const double fd = (lp - lm) / (2 * eps);
    EXPECT_NEAR(grad[i], fd, 1e-6 + 1e-5 * std::max(std::abs(fd), max_abs))
        << name << "[" << i << "]";
  }
}

void gradient_check(GaussiansD g, const Camera& cam, const RasterSettings& s, unsigned seed) {
  const Loss L = random_loss(cam.width, cam.height, seed);
  RasterResultD r;
  rasterize_forward(g, cam, s, r);
  RasterGradsD gr;
  rasterize_backward(g, cam, s, r, L.wc, L.wa, gr);
  auto eval = [&] {
    RasterResultD rr;
    rasterize_forward(g, cam, s, rr);
    return L(rr);
  };
  check_group("means", g.means, gr.means, eval);
  check_group("log_scales", g.log_scales, gr.log_scales, eval);
  check_group("quats", g.quats, gr.quats, eval);
  check_group("opacity_logits", g.opacity_logits, gr.opacity_logits, eval);
  check_group("sh", g.sh, gr.sh, eval);
  // 2D means: shifting the principal point moves every means2d by the same amount without
  // changing anything else (no Jacobian clamp active), so dL/dcx = sum_i dL/du_i.
  for (int axis = 0; axis < 2; ++axis) {
    double analytic = 0;
    for (size_t i = 0; i < g.size(); ++i) analytic += gr.means2d[2 * i + axis];
    Camera c2 = cam;
    const double eps = 1e-6;
    double& pp = axis == 0 ? c2.cx : c2.cy;
    const double keep = pp;
    pp = keep + eps;
    RasterResultD a, b;
    rasterize_forward(g, c2, s, a);
    pp = keep - eps;
    rasterize_forward(g, c2, s, b);
    const double fd = (L(a) - L(b)) / (2 * eps);
    EXPECT_NEAR(analytic, fd, 1e-6 + 1e-5 * std::abs(fd)) << "means2d axis " << axis;
  }
}

// Few Gaussians well inside a 32x32 image, moderate opacities (no 0.99 clamp, no early stop).
GaussiansD small_scene(int sh_degree, unsigned seed) {
  SceneOptions o;
  o.n = 5;
  o.sh_degree = sh_degree;
  o.spread = 0.12;
  o.scale_min = 0.03, o.scale_max = 0.07;
  o.opacity_min = 0.3, o.opacity_max = 0.8;
  return GaussiansD::from(random_scene(o, seed));
}

TEST(RasterGrad, AllParametersSH0) {
  RasterSettings s;
  s.background[0] = 0.3f, s.background[1] = 0.6f, s.background[2] = 0.1f;
  gradient_check(small_scene(0, 21), test_camera(32, 32, 0.45, 0.55), s, 7);
}

TEST(RasterGrad, AllParametersSH3) {
  RasterSettings s;
  s.background[2] = 1.0f;
  gradient_check(small_scene(3, 22), test_camera(32, 32, 0.56, 0.41), s, 8);
}

// A Gaussian whose centre is beyond the Jacobian clamp (x/z limit) but reaches into the image:
// the exact derivative of the clamped Jacobian is used.
TEST(RasterGrad, ClampedJacobian) {
  GaussiansD g;
  g.sh_degree = 1;
  g.means = {1.6, 0.02, 0.0, 0.02, -0.03, 0.05};
  g.log_scales = {std::log(0.4),  std::log(0.15), std::log(0.1),
                  std::log(0.04), std::log(0.05), std::log(0.03)};
  g.quats = {0.9, 0.1, -0.2, 0.3, 0.8, -0.3, 0.1, 0.2};
  g.opacity_logits = {0.5, -0.2};
  g.sh = {1.0, 0.5, 0.2, 0.1,  -0.1, 0.05, 0.02, 0.1,  -0.05, 0.03, 0.0, 0.1,
          0.3, 0.9, 0.4, -0.1, 0.1,  0.05, 0.02, -0.1, 0.05,  0.03, 0.1, 0.0};
  const Camera cam = test_camera(32, 32, 0.5, 0.5);
  RasterResultD r;
  rasterize_forward(g, cam, {}, r);
  ASSERT_GT(r.radii[0], 0);
  ASSERT_GT(r.packed[0], 1.15 * 32);  // the 2D mean: clamp active
  const Loss L = random_loss(32, 32, 3);
  RasterGradsD gr;
  rasterize_backward(g, cam, {}, r, L.wc, L.wa, gr);
  auto eval = [&] {
    RasterResultD rr;
    rasterize_forward(g, cam, {}, rr);
    return L(rr);
  };
  check_group("means", g.means, gr.means, eval);
  check_group("log_scales", g.log_scales, gr.log_scales, eval);
  check_group("quats", g.quats, gr.quats, eval);
}

// The float backward agrees with the double one (same code, different precision).
TEST(RasterGrad, FloatMatchesDouble) {
  SceneOptions o;
  o.n = 40;
  o.sh_degree = 2;
  o.opacity_max = 0.9;
  const Gaussians g = random_scene(o, 31);
  const Camera cam = test_camera(48, 40);
  RasterResult rf;
  rasterize_forward(g, cam, {}, rf);
  Image wc(48, 40, 3), wa(48, 40, 1);
  test::random_upstream(wc, wa, 4);
  RasterGrads gf;
  rasterize_backward(g, cam, {}, rf, wc, wa, gf);
  const GaussiansD gd = GaussiansD::from(g);
  RasterResultD rd;
  rasterize_forward(gd, cam, {}, rd);
  ImageD wcd(48, 40, 3), wad(48, 40, 1);
  wcd.data.assign(wc.data.begin(), wc.data.end());
  wad.data.assign(wa.data.begin(), wa.data.end());
  RasterGradsD gdd;
  rasterize_backward(gd, cam, {}, rd, wcd, wad, gdd);
  auto cmp = [](const char* name, const std::vector<float>& a, const std::vector<double>& b) {
    ASSERT_EQ(a.size(), b.size());
    double num = 0, den = 0;
    for (size_t i = 0; i < a.size(); ++i) num += (a[i] - b[i]) * (a[i] - b[i]), den += b[i] * b[i];
    EXPECT_LT(std::sqrt(num / std::max(den, 1e-30)), 1e-3) << name;
  };
  cmp("means", gf.means, gdd.means);
  cmp("log_scales", gf.log_scales, gdd.log_scales);
  cmp("quats", gf.quats, gdd.quats);
  cmp("opacity", gf.opacity_logits, gdd.opacity_logits);
  cmp("sh", gf.sh, gdd.sh);
  cmp("means2d", gf.means2d, gdd.means2d);
}

}  // namespace
}  // namespace ks

namespace ks {
namespace {

TEST(Raster, EmptyAndDegenerateInputs) {
  const Camera cam = test_camera(20, 18);
  RasterSettings s;
  s.background[0] = 0.25f;
  Gaussians empty;
  RasterResult r;
  rasterize_forward(empty, cam, s, r);
  for (int i = 0; i < 20 * 18; ++i) {
    EXPECT_EQ(r.color.data[3 * i], 0.25f);
    EXPECT_EQ(r.alpha.data[i], 0.f);
  }
  RasterGrads gr;
  Image dc(20, 18, 3, 1.f);
  rasterize_backward(empty, cam, s, r, dc, Image(), gr);
  EXPECT_TRUE(gr.means.empty());
  // NaN mean, zero quaternion and a huge Gaussian: culled or clipped, never a crash.
  Gaussians g;
  g.resize(3);
  g.means = {std::nanf(""), 0, 0, 0, 0, 0, 0.1f, 0, 0};
  g.quats[4] = 0;                                         // second: zero quaternion
  for (int a = 0; a < 3; ++a) g.log_scales[6 + a] = 8.f;  // third: e^8 m
  rasterize_forward(g, cam, s, r);
  EXPECT_EQ(r.radii[0], 0);
  EXPECT_EQ(r.radii[1], 0);
  for (float v : r.color.data) EXPECT_TRUE(std::isfinite(v));
  rasterize_backward(g, cam, s, r, dc, Image(), gr);
  for (float v : gr.means) EXPECT_TRUE(std::isfinite(v));
  // Mismatched gradient image sizes are a clear error.
  EXPECT_THROW(rasterize_backward(g, cam, s, r, Image(5, 5, 3), Image(), gr), Error);
}

}  // namespace
}  // namespace ks
