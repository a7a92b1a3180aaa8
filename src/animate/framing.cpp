#include "animate/framing.hpp"

#include <algorithm>
#include <cmath>

#include "avatar/pose.hpp"

namespace ks {

void motion_bounds(const Avatar& a, const Motion& m, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  lo.setConstant(1e30);
  hi.setConstant(-1e30);
  Gaussians g;
  const size_t step = std::max<size_t>(1, m.frames.size() / 16);
  for (size_t f = 0; f < m.frames.size(); f += step) {
    pose_avatar(a, m.frames[f], g, nullptr, f > 0);
    const size_t stride = std::max<size_t>(1, g.size() / 20000);
    for (size_t i = 0; i < g.size(); i += stride) {
      if (g.opacity_logits[i] < -2.f) continue;
      const Eigen::Vector3d p(g.means[3 * i], g.means[3 * i + 1], g.means[3 * i + 2]);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  if (lo.x() > hi.x()) lo = hi = Eigen::Vector3d::Zero();
  const Eigen::Vector3d grow = (Eigen::Vector3d::Constant(0.1) - (hi - lo)).cwiseMax(0.0) * 0.5;
  lo -= grow;
  hi += grow;
}

std::vector<Camera> playback_cameras(const std::string& spec, const Eigen::Vector3d& lo,
                                     const Eigen::Vector3d& hi, int width, int height, int frames) {
  std::vector<Camera> cams;
  if (spec != "front" && spec != "orbit") {
    Camera c = Camera::load(spec);
    if (c.width != width || c.height != height) c = scale_camera(c, width, height);
    cams.assign(size_t(frames), c);
    return cams;
  }
  const double vfov = 30.0;
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const Eigen::Vector3d ext = hi - lo;
  const double tan_v = std::tan(0.5 * vfov * M_PI / 180.0);
  const double tan_h = tan_v * double(width) / height;
  const double horiz = std::max(ext.x(), ext.z());  // the orbit sees the widest side
  const double half_h = 0.5 * ext.y() * 1.12, half_w = 0.5 * horiz * 1.12;
  const double dist = std::max(half_h / tan_v, half_w / tan_h) + 0.5 * horiz;
  for (int f = 0; f < frames; ++f) {
    const double th = spec == "orbit" ? 2.0 * M_PI * f / std::max(frames, 1) : 0.0;
    const Eigen::Vector3d eye = centre + dist * Eigen::Vector3d(std::sin(th), 0.0, std::cos(th));
    cams.push_back(Camera::look_at_fov(eye, centre, width, height, vfov));
  }
  return cams;
}

}  // namespace ks
