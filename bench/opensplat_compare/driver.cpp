// Times OpenSplat's CPU rasterization path (project + SH colour + rasterize, forward and autograd
// backward) on a 3DGS .ply seen by a kinesplat camera JSON. Built and run by
// bench/opensplat_compare.sh against a separate OpenSplat checkout; not part of kinesplat's build.
//
//   opensplat_driver --ply SCENE.ply --camera CAM.json [--threads N] [--steps K] [--warmup W]
//                    [--out IMG.png] [--compare REF.png]
//
// Prints per-step median / min wall time of forward, backward and forward + backward, and with
// --compare the PSNR between the forward image and a reference PNG (e.g. `kinesplat render`).
#include <torch/torch.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/camera.hpp"
#include "gaussians/ply.hpp"
#include "gsplat.hpp"
#include "project_gaussians.hpp"
#include "rasterize_gaussians.hpp"

namespace {

struct Scene {
  int64_t n = 0;
  int sh_bases = 1;
  torch::Tensor means, log_scales, quats, opacity_logits, sh;  // sh: [n, bases, 3]
};

// The scene through kinesplat's own readers (gaussians/ply, core/camera), copied into tensors.
// ks::Gaussians' SH layout, [n][k][rgb], is the [n, bases, 3] tensor OpenSplat takes.
Scene read_scene_ply(const std::string& path) {
  const ks::Gaussians g = ks::read_ply(path);
  Scene s;
  s.n = int64_t(g.size());
  s.sh_bases = g.coeffs();
  if (s.n == 0) throw std::runtime_error(path + ": no Gaussians");
  auto copy = [](const std::vector<float>& v, std::vector<int64_t> shape) {
    return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
  };
  s.means = copy(g.means, {s.n, 3});
  s.log_scales = copy(g.log_scales, {s.n, 3});
  s.quats = copy(g.quats, {s.n, 4});
  s.opacity_logits = copy(g.opacity_logits, {s.n, 1});
  s.sh = copy(g.sh, {s.n, s.sh_bases, 3});
  return s;
}

struct Cam {
  int width = 0, height = 0;
  float fx = 0, fy = 0, cx = 0, cy = 0;
  float R[3][3] = {}, t[3] = {};
};

Cam read_camera(const std::string& path) {
  const ks::Camera k = ks::Camera::load(path);  // validates keys, shapes, R and the focal length
  Cam c;
  c.width = k.width;
  c.height = k.height;
  c.fx = float(k.fx), c.fy = float(k.fy), c.cx = float(k.cx), c.cy = float(k.cy);
  for (int r = 0; r < 3; ++r) {
    c.t[r] = float(k.t(r));
    for (int j = 0; j < 3; ++j) c.R[r][j] = float(k.R(r, j));
  }
  return c;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Args {
  std::string ply, camera, out, compare;
  int threads = 1, steps = 10, warmup = 1;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto val = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(k + " needs a value");
      return argv[++i];
    };
    if (k == "--ply")
      a.ply = val();
    else if (k == "--camera")
      a.camera = val();
    else if (k == "--out")
      a.out = val();
    else if (k == "--compare")
      a.compare = val();
    else if (k == "--threads")
      a.threads = std::stoi(val());
    else if (k == "--steps")
      a.steps = std::stoi(val());
    else if (k == "--warmup")
      a.warmup = std::stoi(val());
    else
      throw std::runtime_error("unknown argument " + k);
  }
  if (a.ply.empty() || a.camera.empty())
    throw std::runtime_error("--ply and --camera are required");
  if (a.threads < 1 || a.steps < 1 || a.warmup < 0) throw std::runtime_error("bad counts");
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const Args a = parse(argc, argv);
    torch::set_num_threads(a.threads);
    const Scene s = read_scene_ply(a.ply);
    const Cam c = read_camera(a.camera);
    const int W = c.width, H = c.height;
    auto opt = torch::TensorOptions().dtype(torch::kFloat32);

    // World-to-camera (OpenCV axes: x right, y down, z forward), as gsplat's view matrix.
    torch::Tensor view = torch::eye(4, opt);
    for (int r = 0; r < 3; ++r) {
      view[r][3] = c.t[r];
      for (int k = 0; k < 3; ++k) view[r][k] = c.R[r][k];
    }
    // OpenSplat's CPU projection maps NDC x to u = 0.5 ((x + 1) W - 1), pixel centres at integer
    // u. With x = (2 fx / W) X/Z + (2 cx - W) / W this is u = fx X/Z + cx - 0.5, i.e. kinesplat's
    // camera with its pixel centres at integer + 0.5. Depth terms as OpenSplat (near 0.001,
    // far 1000); only the w row matters for the pixel position.
    const float zn = 0.001f, zf = 1000.f;
    torch::Tensor proj = torch::zeros({4, 4}, opt);
    proj[0][0] = 2.f * c.fx / W;
    proj[0][2] = (2.f * c.cx - W) / W;
    proj[1][1] = 2.f * c.fy / H;
    proj[1][2] = (2.f * c.cy - H) / H;
    proj[2][2] = (zf + zn) / (zf - zn);
    proj[2][3] = -zf * zn / (zf - zn);
    proj[3][2] = 1.f;
    const torch::Tensor full_proj = torch::matmul(proj, view);
    // Camera centre in world coordinates: -R^T t.
    const torch::Tensor Rm =
        view.index({torch::indexing::Slice(0, 3), torch::indexing::Slice(0, 3)});
    const torch::Tensor tv = view.index({torch::indexing::Slice(0, 3), 3});
    const torch::Tensor centre = -torch::matmul(Rm.transpose(0, 1), tv);
    const torch::Tensor background = torch::zeros({3}, opt);

    // Leaves with gradients, as a trainer holds them.
    torch::Tensor means = s.means.clone().set_requires_grad(true);
    torch::Tensor log_scales = s.log_scales.clone().set_requires_grad(true);
    torch::Tensor quats = s.quats.clone().set_requires_grad(true);
    torch::Tensor opac = s.opacity_logits.clone().set_requires_grad(true);
    torch::Tensor sh = s.sh.clone().set_requires_grad(true);
    const int degree = int(std::lround(std::sqrt(double(s.sh_bases)))) - 1;
    // A fixed random image the loss is weighted by: L = sum(image * weights).
    torch::manual_seed(7);
    const torch::Tensor weights = torch::rand({H, W, 3}, opt) * 2e-3f - 1e-3f;

    auto forward = [&]() {
      auto p = ProjectGaussiansCPU::apply(means, torch::exp(log_scales), 1.f,
                                          quats / quats.norm(2, {-1}, true), view, full_proj, c.fx,
                                          c.fy, c.cx, c.cy, H, W);
      torch::Tensor dirs = means.detach() - centre;
      dirs = dirs / dirs.norm(2, {-1}, true);
      torch::Tensor rgb = compute_sh_forward_tensor_cpu(int(s.n), degree, degree, dirs, sh);
      rgb = torch::clamp_min(rgb + 0.5f, 0.f);
      return RasterizeGaussiansCPU::apply(p[0], p[1], p[2], rgb, torch::sigmoid(opac), p[3], p[4],
                                          H, W, background);
    };
    auto zero_grads = [&]() {
      for (torch::Tensor* t : {&means, &log_scales, &quats, &opac, &sh})
        if (t->grad().defined()) t->mutable_grad().zero_();
    };

    using clock = std::chrono::steady_clock;
    auto ms = [](clock::time_point a, clock::time_point b) {
      return std::chrono::duration<double, std::milli>(b - a).count();
    };
    torch::Tensor img;
    for (int i = 0; i < a.warmup; ++i) {
      zero_grads();
      img = forward();
      (img * weights).sum().backward();
    }
    std::vector<double> fwd, bwd, both;
    for (int i = 0; i < a.steps; ++i) {
      zero_grads();
      const auto t0 = clock::now();
      img = forward();
      torch::Tensor loss = (img * weights).sum();
      const auto t1 = clock::now();
      loss.backward();
      const auto t2 = clock::now();
      fwd.push_back(ms(t0, t1));
      bwd.push_back(ms(t1, t2));
      both.push_back(ms(t0, t2));
    }
    const double gnorm = means.grad().norm().item<double>() + sh.grad().norm().item<double>();
    std::printf("opensplat-cpu: %lld gaussians (SH degree %d), %dx%d, torch threads %d\n",
                (long long)s.n, degree, W, H, torch::get_num_threads());
    std::printf("forward: median %.1f ms, min %.1f ms over %d steps\n", median(fwd),
                *std::min_element(fwd.begin(), fwd.end()), a.steps);
    std::printf("backward: median %.1f ms, min %.1f ms\n", median(bwd),
                *std::min_element(bwd.begin(), bwd.end()));
    std::printf("forward+backward: median %.1f ms, min %.1f ms (gradient check value %.4g)\n",
                median(both), *std::min_element(both.begin(), both.end()), gnorm);

    const torch::Tensor out = img.detach().clamp(0.f, 1.f).contiguous();
    if (!a.out.empty() || !a.compare.empty()) {
      // Forward image as 16-bit RGB; OpenCV stores BGR.
      cv::Mat rgb16(H, W, CV_16UC3);
      const float* p = out.data_ptr<float>();
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          for (int k = 0; k < 3; ++k)
            rgb16.at<cv::Vec3w>(y, x)[2 - k] =
                uint16_t(std::lround(p[(size_t(y) * W + x) * 3 + k] * 65535.f));
      if (!a.out.empty() && !cv::imwrite(a.out, rgb16))
        throw std::runtime_error(a.out + ": cannot write");
      if (!a.compare.empty()) {
        cv::Mat ref = cv::imread(a.compare, cv::IMREAD_UNCHANGED);
        if (ref.empty()) throw std::runtime_error(a.compare + ": cannot read");
        if (ref.rows != H || ref.cols != W || ref.channels() < 3)
          throw std::runtime_error(a.compare + ": size or channels differ");
        const double scale = ref.depth() == CV_16U ? 1.0 / 65535 : 1.0 / 255;
        cv::Mat r;
        ref.convertTo(r, CV_64F, scale);
        // Over the whole image, and over the pixels either image covers (not background black).
        double se = 0, se_cov = 0, max_diff = 0;
        size_t covered = 0;
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            double px = 0;
            bool cov = false;
            for (int k = 0; k < 3; ++k) {
              const double o = p[(size_t(y) * W + x) * 3 + k];
              const double q = r.ptr<double>(y)[x * r.channels() + (2 - k)];
              px += (o - q) * (o - q);
              max_diff = std::max(max_diff, std::abs(o - q));
              cov = cov || o > 1.0 / 255 || q > 1.0 / 255;
            }
            se += px;
            if (cov) se_cov += px, ++covered;
          }
        auto psnr = [](double sum, double count) {
          return 10 * std::log10(1.0 / std::max(sum / std::max(count, 1.0), 1e-20));
        };
        std::printf(
            "PSNR against %s: %.2f dB over the image, %.2f dB over the %.1f%% covered pixels, "
            "max difference %.3f\n",
            a.compare.c_str(), psnr(se, 3.0 * W * H), psnr(se_cov, 3.0 * covered),
            100.0 * covered / (double(W) * H), max_diff);
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
