// Posing on the device (RasterizerCuda::upload_skinned / pose) against the CPU's lbs_forward,
// the reference (body/lbs.hpp). Skips, saying why, without a CUDA build or device (CI).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "body/lbs.hpp"
#include "core/error.hpp"
#include "raster/avatar_cloud.hpp"
#include "raster_cuda/need_gpu.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace ks {
namespace {

// A skinned cloud: K = 4 joints of 24 per Gaussian with random weights summing to one (some
// zero), random rigid joint transforms, small pose offsets and random unit normals.
struct Skinned {
  Gaussians c;
  std::vector<int> joints;
  std::vector<float> weights, offsets, normals;
  std::vector<Eigen::Matrix4d> transforms;
};

Skinned make_skinned(size_t n, unsigned seed) {
  Skinned s;
  s.c = make_avatar_cloud(n, seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f), sym(-1.f, 1.f);
  constexpr int J = 24, K = 4;
  for (size_t i = 0; i < n; ++i) {
    float sum = 0;
    for (int k = 0; k < K; ++k) {
      s.joints.push_back(int(rng() % J));
      const float w = (k > 0 && u(rng) < 0.3f) ? 0.f : u(rng) + 0.05f;
      s.weights.push_back(w);
      sum += w;
    }
    for (int k = 0; k < K; ++k) s.weights[K * i + size_t(k)] /= sum;
    for (int k = 0; k < 3; ++k) s.offsets.push_back(0.01f * sym(rng));
    Eigen::Vector3f nv(sym(rng), sym(rng), sym(rng));
    nv = nv.norm() > 1e-3f ? nv.normalized() : Eigen::Vector3f::UnitZ();
    for (int k = 0; k < 3; ++k) s.normals.push_back(nv[k]);
  }
  for (int j = 0; j < J; ++j) {
    const Eigen::Vector3d axis = Eigen::Vector3d(sym(rng), sym(rng), sym(rng)).normalized();
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(1.5 * u(rng), axis).toRotationMatrix();
    T.topRightCorner<3, 1>() = Eigen::Vector3d(sym(rng), sym(rng), sym(rng)) * 0.3;
    s.transforms.push_back(T);
  }
  return s;
}

// Largest |a - b| over the arrays; for quaternions (step 4) the closer of q and -q.
float max_diff(const std::vector<float>& a, const std::vector<float>& b, int step = 1) {
  EXPECT_EQ(a.size(), b.size());
  float m = 0;
  for (size_t i = 0; i + size_t(step) <= std::min(a.size(), b.size()); i += size_t(step)) {
    float d = 0, e = 0;
    for (int k = 0; k < step; ++k) {
      d = std::max(d, std::abs(a[i + size_t(k)] - b[i + size_t(k)]));
      e = std::max(e, std::abs(a[i + size_t(k)] + b[i + size_t(k)]));
    }
    m = std::max(m, step == 4 ? std::min(d, e) : d);
  }
  return m;
}

TEST(LbsCuda, PosingMatchesTheCpu) {
  KS_NEED_GPU();
  const size_t n = 20011;  // not a multiple of any block
  const Skinned s = make_skinned(n, 5);
  BackfaceCull cull;
  cull.normals = &s.normals;
  cull.eye = Eigen::Vector3d(0.2, 1.0, 3.0);
  cull.threshold = 0.4f;
  cuda::RasterizerCuda r;
  r.upload_skinned(s.c, s.joints, s.weights, s.normals);
  for (const bool extras : {true, false}) {
    Gaussians cpu, gpu;
    lbs_forward(s.c, extras ? s.offsets.data() : nullptr, s.joints, s.weights, s.transforms, cpu,
                nullptr, extras ? &cull : nullptr);
    r.pose(s.transforms, extras ? s.offsets.data() : nullptr, extras ? &cull : nullptr);
    r.download_gaussians(gpu);
    ASSERT_EQ(gpu.size(), n);
    const float dm = max_diff(gpu.means, cpu.means), dq = max_diff(gpu.quats, cpu.quats, 4);
    size_t culled_cpu = 0, differ = 0;
    for (size_t i = 0; i < n; ++i) {
      culled_cpu += cpu.opacity_logits[i] == kCulledOpacityLogit;
      differ += gpu.opacity_logits[i] != cpu.opacity_logits[i];
    }
    std::printf("%s: means %.2e, rotations %.2e largest difference; %zu culled, %zu differ\n",
                extras ? "offsets + culling" : "plain", dm, dq, culled_cpu, differ);
    EXPECT_LE(dm, 2e-5f);  // means within about 1.5 m of the origin
    EXPECT_LE(dq, 2e-5f);
    // Culling is a threshold on a float expression: rounding may flip a Gaussian on its edge.
    EXPECT_LE(differ, n / 1000);
    if (extras) {
      EXPECT_GT(culled_cpu, n / 10);
    }
    EXPECT_EQ(gpu.log_scales, cpu.log_scales);
    EXPECT_EQ(gpu.sh, cpu.sh);
    EXPECT_EQ(gpu.sh_degree, cpu.sh_degree);
  }
}

TEST(LbsCuda, PosedOnTheDeviceRendersAsPosedOnTheHost) {
  KS_NEED_GPU();
  const Skinned s = make_skinned(30000, 7);
  Gaussians cpu;
  lbs_forward(s.c, s.offsets.data(), s.joints, s.weights, s.transforms, cpu);
  const Camera cam = avatar_camera(160, 240);
  cuda::RasterizerCuda a, b;
  RasterResult ra, rb;
  a.upload_skinned(s.c, s.joints, s.weights, {});
  a.pose(s.transforms, s.offsets.data(), nullptr);
  a.forward(cam, RasterSettings{});
  a.download(ra);
  b.upload(cpu);
  b.forward(cam, RasterSettings{});
  b.download(rb);
  double se = 0;
  for (size_t p = 0; p < ra.color.data.size(); ++p)
    se += double(ra.color.data[p] - rb.color.data[p]) * (ra.color.data[p] - rb.color.data[p]);
  const double mse = se / double(ra.color.data.size());
  const double psnr = mse <= 0 ? 200.0 : 10 * std::log10(1.0 / mse);
  std::printf("image posed on the device against posed on the host: %.1f dB\n", psnr);
  EXPECT_GE(psnr, 60.0);
}

TEST(LbsCuda, BadInputsAreRefused) {
  KS_NEED_GPU();
  const Skinned s = make_skinned(500, 3);
  cuda::RasterizerCuda r;
  EXPECT_THROW(r.pose(s.transforms, nullptr, nullptr), Error);  // nothing uploaded
  std::vector<int> j = s.joints;
  j.pop_back();
  EXPECT_THROW(r.upload_skinned(s.c, j, s.weights, {}), Error);
  j = s.joints;
  j[7] = -1;
  EXPECT_THROW(r.upload_skinned(s.c, j, s.weights, {}), Error);
  std::vector<float> nrm = s.normals;
  nrm.pop_back();
  EXPECT_THROW(r.upload_skinned(s.c, s.joints, s.weights, nrm), Error);
  r.upload_skinned(s.c, s.joints, s.weights, s.normals);
  std::vector<Eigen::Matrix4d> few(s.transforms.begin(), s.transforms.begin() + 3);
  EXPECT_THROW(r.pose(few, nullptr, nullptr), Error);
  BackfaceCull cull;
  cull.threshold = 1.5f;
  EXPECT_THROW(r.pose(s.transforms, nullptr, &cull), Error);
  r.pose(s.transforms, nullptr, nullptr);
  // A whole upload afterwards ends the skinned set.
  r.upload(s.c);
  EXPECT_THROW(r.pose(s.transforms, nullptr, nullptr), Error);
}

}  // namespace
}  // namespace ks
