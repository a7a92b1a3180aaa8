#include "raster/avatar_cloud.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "raster/sh.hpp"

namespace ks {
namespace {

struct Part {
  // Capsule from a to b with radius r (a == b: ellipsoid with radii rad around a).
  Eigen::Vector3d a, b;
  Eigen::Vector3d rad;
  bool ellipsoid;
  Eigen::Vector3d colour;
  double area() const {
    if (ellipsoid) {
      // Knud Thomsen's approximation of the ellipsoid surface area.
      const double p = 1.6075, x = std::pow(rad.x(), p), y = std::pow(rad.y(), p),
                   z = std::pow(rad.z(), p);
      return 4 * M_PI * std::pow((x * y + x * z + y * z) / 3, 1 / p);
    }
    return 2 * M_PI * rad.x() * (b - a).norm() + 4 * M_PI * rad.x() * rad.x();
  }
};

Part ell(Eigen::Vector3d c, Eigen::Vector3d r, Eigen::Vector3d col) {
  return {c, c, r, true, col};
}
Part cap(Eigen::Vector3d a, Eigen::Vector3d b, double r, Eigen::Vector3d col) {
  return {a, b, {r, r, r}, false, col};
}

}  // namespace

Gaussians make_avatar_cloud(size_t n, unsigned seed) {
  const Eigen::Vector3d skin(0.85, 0.65, 0.52), shirt(0.2, 0.35, 0.7), trousers(0.15, 0.15, 0.2),
      hair(0.15, 0.1, 0.07), shoes(0.1, 0.1, 0.1);
  std::vector<Part> parts = {
      ell({0, 1.58, 0}, {0.085, 0.11, 0.1}, skin),           // head
      ell({0, 1.64, -0.01}, {0.09, 0.07, 0.1}, hair),        // hair
      cap({0, 1.42, 0}, {0, 1.5, 0}, 0.05, skin),            // neck
      ell({0, 1.2, 0}, {0.18, 0.24, 0.11}, shirt),           // chest
      ell({0, 0.98, 0}, {0.16, 0.14, 0.1}, trousers),        // pelvis
      cap({-0.21, 1.36, 0}, {-0.26, 1.08, 0}, 0.05, shirt),  // upper arms
      cap({0.21, 1.36, 0}, {0.26, 1.08, 0}, 0.05, shirt),
      cap({-0.26, 1.08, 0}, {-0.29, 0.84, 0.03}, 0.04, skin),  // forearms
      cap({0.26, 1.08, 0}, {0.29, 0.84, 0.03}, 0.04, skin),
      ell({-0.3, 0.77, 0.03}, {0.035, 0.07, 0.025}, skin),  // hands
      ell({0.3, 0.77, 0.03}, {0.035, 0.07, 0.025}, skin),
      cap({-0.09, 0.9, 0}, {-0.1, 0.5, 0}, 0.075, trousers),  // thighs
      cap({0.09, 0.9, 0}, {0.1, 0.5, 0}, 0.075, trousers),
      cap({-0.1, 0.5, 0}, {-0.1, 0.1, 0}, 0.055, trousers),  // shins
      cap({0.1, 0.5, 0}, {0.1, 0.1, 0}, 0.055, trousers),
      ell({-0.1, 0.04, 0.05}, {0.05, 0.04, 0.12}, shoes),  // feet
      ell({0.1, 0.04, 0.05}, {0.05, 0.04, 0.12}, shoes),
  };
  std::vector<double> cdf;
  double total = 0;
  for (const auto& p : parts) cdf.push_back(total += p.area());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> N01(0, 1);
  Gaussians g;
  g.sh_degree = 3;
  g.resize(n);
  const int K = g.coeffs();
  for (size_t i = 0; i < n; ++i) {
    const double pick = U(rng) * total;
    size_t k = 0;
    while (k + 1 < parts.size() && cdf[k] < pick) ++k;
    const Part& p = parts[k];
    Eigen::Vector3d d(N01(rng), N01(rng), N01(rng));
    d.normalize();
    Eigen::Vector3d pos;
    if (p.ellipsoid) {
      pos = p.a + d.cwiseProduct(p.rad);
    } else {
      const Eigen::Vector3d axis = (p.b - p.a);
      const double len = axis.norm();
      const Eigen::Vector3d ax = axis / len;
      const double side = 2 * M_PI * p.rad.x() * len, caps = 4 * M_PI * p.rad.x() * p.rad.x();
      if (U(rng) * (side + caps) < side) {
        Eigen::Vector3d r = d - ax * d.dot(ax);
        if (r.norm() < 1e-6) r = ax.unitOrthogonal();
        pos = p.a + ax * (U(rng) * len) + r.normalized() * p.rad.x();
      } else {
        pos = (d.dot(ax) > 0 ? p.b : p.a) + d * p.rad.x();
      }
    }
    for (int a = 0; a < 3; ++a) g.means[3 * i + a] = float(pos[a]);
    // Flat discs tangent to the surface: in-plane scales mostly 2-6 mm (log-uniform), 15% of
    // them 6-16 mm; the normal scale a third of the smaller one.
    Eigen::Vector3d normal =
        p.ellipsoid
            ? Eigen::Vector3d(d.cwiseQuotient(p.rad)).normalized()
            : Eigen::Vector3d(pos - p.a -
                              (p.b - p.a).normalized() * (pos - p.a).dot((p.b - p.a).normalized()))
                  .normalized();
    if (!std::isfinite(normal.norm()) || normal.norm() < 0.5) normal = d;
    const double s0 = U(rng) < 0.85 ? std::exp(std::log(0.002) + U(rng) * std::log(3.0))
                                    : std::exp(std::log(0.006) + U(rng) * std::log(16.0 / 6.0));
    const double s1 = s0 * (0.6 + 0.8 * U(rng));
    g.log_scales[3 * i] = float(std::log(s0));
    g.log_scales[3 * i + 1] = float(std::log(s1));
    g.log_scales[3 * i + 2] = float(std::log(std::min(s0, s1) / 3));
    const double ang = 2 * M_PI * U(rng);
    const Eigen::Vector3d t0 = normal.unitOrthogonal(), t1 = normal.cross(t0);
    const Eigen::Vector3d e0 = std::cos(ang) * t0 + std::sin(ang) * t1, e1 = normal.cross(e0);
    Eigen::Matrix3d Rm;
    Rm.col(0) = e0, Rm.col(1) = e1, Rm.col(2) = normal;
    Eigen::Quaterniond q(Rm);
    q.normalize();
    g.quats[4 * i] = float(q.w()), g.quats[4 * i + 1] = float(q.x());
    g.quats[4 * i + 2] = float(q.y()), g.quats[4 * i + 3] = float(q.z());
    const double op = U(rng) < 0.8 ? 0.9 + 0.09 * U(rng) : 0.2 + 0.7 * U(rng);
    g.opacity_logits[i] = float(std::log(op / (1 - op)));
    for (int c = 0; c < 3; ++c) {
      const double col = std::clamp(p.colour[c] + 0.05 * N01(rng), 0.0, 1.0);
      g.sh[(i * K) * 3 + c] = float((col - 0.5) / sh::kC0);
      for (int kk = 1; kk < K; ++kk) g.sh[(i * K + kk) * 3 + c] = float(0.03 * N01(rng));
    }
  }
  return g;
}

Camera avatar_camera(int width, int height) {
  // Vertical field of view so that ~1.95 m around the body's centre fills the image height.
  const double dist = 3.0;
  const double vfov = 2 * std::atan(0.975 / dist) * 180 / M_PI;
  return Camera::look_at_fov({0, 0.88, dist}, {0, 0.86, 0}, width, height, vfov);
}

}  // namespace ks
