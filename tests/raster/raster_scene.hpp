#pragma once
// Test helpers: random Gaussian scenes and an independent brute-force reference renderer
// (double precision, no tiles, no sorting tricks: every Gaussian is tested at every pixel).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "core/camera.hpp"
#include "gaussians/gaussians.hpp"
#include "raster/rasterizer.hpp"

namespace ks::test {

struct SceneOptions {
  int n = 20;
  int sh_degree = 0;
  double scale_min = 0.02, scale_max = 0.08;
  double opacity_min = 0.3, opacity_max = 0.95;
  double spread = 0.35;  // half-extent of the cube holding the means
};

// A camera looking at the origin from +Z at distance 2 with an off-centre principal point.
inline Camera test_camera(int w, int h, double cx_frac = 0.43, double cy_frac = 0.57) {
  const double f = 0.9 * h;
  return Camera::look_at({0.1, 0.05, 2.0}, {0, 0, 0}, {0, 1, 0}, w, h, f, f * 1.1, cx_frac * w,
                         cy_frac * h);
}

inline Gaussians random_scene(const SceneOptions& o, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Gaussians g;
  g.sh_degree = o.sh_degree;
  g.resize(size_t(o.n));
  const int K = g.coeffs();
  for (int i = 0; i < o.n; ++i) {
    for (int a = 0; a < 3; ++a) {
      g.means[3 * i + a] = float(o.spread * (2 * U(rng) - 1));
      g.log_scales[3 * i + a] = float(std::log(o.scale_min + (o.scale_max - o.scale_min) * U(rng)));
    }
    for (int a = 0; a < 4; ++a) g.quats[4 * i + a] = float(2 * U(rng) - 1);
    const double op = o.opacity_min + (o.opacity_max - o.opacity_min) * U(rng);
    g.opacity_logits[i] = float(std::log(op / (1 - op)));
    for (int k = 0; k < K; ++k)
      for (int c = 0; c < 3; ++c)
        g.sh[(size_t(i) * K + k) * 3 + c] =
            float(k == 0 ? 0.3 + 1.2 * U(rng) : 0.25 * (2 * U(rng) - 1));
  }
  return g;
}

// Upstream gradients for a backward pass: dL/dcolour then dL/dalpha uniform in [-1, 1].
inline void random_upstream(Image& wc, Image& wa, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(-1, 1);
  for (float& v : wc.data) v = U(rng);
  for (float& v : wa.data) v = U(rng);
}

struct RefImage {
  int w = 0, h = 0;
  std::vector<double> color, alpha, depth;
};

// Independent reference: follows docs/rasterizer.md literally, pixel by pixel.
inline RefImage reference_render(const Gaussians& g, const Camera& cam, const RasterSettings& s) {
  const int W = cam.width, H = cam.height, N = int(g.size()), K = g.coeffs(), deg = g.sh_degree;
  struct P {
    double u, v, qa, qb, qc, o, z, col[3];
  };
  std::vector<P> ps;
  for (int i = 0; i < N; ++i) {
    Eigen::Vector3d m(g.means[3 * i], g.means[3 * i + 1], g.means[3 * i + 2]);
    Eigen::Vector3d pc = cam.R * m + cam.t;
    if (pc.z() < s.near_plane) continue;
    const double o = 1.0 / (1.0 + std::exp(-double(g.opacity_logits[i])));
    Eigen::Quaterniond q(g.quats[4 * i], g.quats[4 * i + 1], g.quats[4 * i + 2],
                         g.quats[4 * i + 3]);
    q.normalize();
    Eigen::Vector3d sc(std::exp(double(g.log_scales[3 * i])),
                       std::exp(double(g.log_scales[3 * i + 1])),
                       std::exp(double(g.log_scales[3 * i + 2])));
    Eigen::Matrix3d Rq = q.toRotationMatrix();
    Eigen::Matrix3d cov = Rq * sc.cwiseAbs2().asDiagonal() * Rq.transpose();
    // Jacobian of the perspective map with x/z, y/z clamped to [-0.15, 1.15] of the image.
    const double xz =
        std::clamp(pc.x() / pc.z(), (-0.15 * W - cam.cx) / cam.fx, (1.15 * W - cam.cx) / cam.fx);
    const double yz =
        std::clamp(pc.y() / pc.z(), (-0.15 * H - cam.cy) / cam.fy, (1.15 * H - cam.cy) / cam.fy);
    Eigen::Matrix<double, 2, 3> J;
    J << cam.fx / pc.z(), 0, -cam.fx * xz / pc.z(), 0, cam.fy / pc.z(), -cam.fy * yz / pc.z();
    Eigen::Matrix2d c2 = J * cam.R * cov * cam.R.transpose() * J.transpose();
    c2(0, 0) += s.low_pass;
    c2(1, 1) += s.low_pass;
    Eigen::Matrix2d inv = c2.inverse();
    P p;
    p.u = cam.fx * pc.x() / pc.z() + cam.cx;
    p.v = cam.fy * pc.y() / pc.z() + cam.cy;
    p.qa = inv(0, 0), p.qb = inv(0, 1), p.qc = inv(1, 1), p.o = o, p.z = pc.z();
    Eigen::Vector3d dir = (m - cam.centre()).normalized();
    const double x = dir.x(), y = dir.y(), z = dir.z();
    double b[16] = {0.28209479177387814,
                    -0.4886025119029199 * y,
                    0.4886025119029199 * z,
                    -0.4886025119029199 * x,
                    1.0925484305920792 * x * y,
                    -1.0925484305920792 * y * z,
                    0.31539156525252005 * (2 * z * z - x * x - y * y),
                    -1.0925484305920792 * x * z,
                    0.5462742152960396 * (x * x - y * y),
                    -0.5900435899266435 * y * (3 * x * x - y * y),
                    2.890611442640554 * x * y * z,
                    -0.4570457994644658 * y * (4 * z * z - x * x - y * y),
                    0.3731763325901154 * z * (2 * z * z - 3 * x * x - 3 * y * y),
                    -0.4570457994644658 * x * (4 * z * z - x * x - y * y),
                    1.445305721320277 * z * (x * x - y * y),
                    -0.5900435899266435 * x * (x * x - 3 * y * y)};
    (void)deg;
    for (int c = 0; c < 3; ++c) {
      double v = 0.5;
      for (int k = 0; k < K; ++k) v += b[k] * g.sh[(size_t(i) * K + k) * 3 + c];
      p.col[c] = std::max(v, 0.0);
    }
    ps.push_back(p);
  }
  std::stable_sort(ps.begin(), ps.end(), [](const P& a, const P& b) { return a.z < b.z; });
  RefImage r;
  r.w = W, r.h = H;
  r.color.assign(size_t(W) * H * 3, 0), r.alpha.assign(size_t(W) * H, 0);
  r.depth.assign(size_t(W) * H, 0);
  for (int py = 0; py < H; ++py)
    for (int px = 0; px < W; ++px) {
      double T = 1, C[3] = {0, 0, 0}, D = 0;
      for (const P& p : ps) {
        const double dx = p.u - (px + 0.5), dy = p.v - (py + 0.5);
        const double power = -0.5 * (p.qa * dx * dx + p.qc * dy * dy) - p.qb * dx * dy;
        if (power > 0) continue;
        const double a = std::min(0.99, p.o * std::exp(power));
        if (a < 1.0 / 255.0) continue;
        if (T * (1 - a) < 1e-4) break;
        for (int c = 0; c < 3; ++c) C[c] += p.col[c] * a * T;
        D += p.z * a * T;
        T *= 1 - a;
      }
      const size_t pix = size_t(py) * W + px;
      for (int c = 0; c < 3; ++c) r.color[3 * pix + c] = C[c] + T * s.background[c];
      r.alpha[pix] = 1 - T;
      r.depth[pix] = D;
    }
  return r;
}

inline double psnr(const std::vector<double>& a, const std::vector<float>& b) {
  double se = 0;
  for (size_t i = 0; i < a.size(); ++i) se += (a[i] - b[i]) * (a[i] - b[i]);
  const double mse = se / double(a.size());
  return mse <= 0 ? 200.0 : 10 * std::log10(1.0 / mse);
}

}  // namespace ks::test
