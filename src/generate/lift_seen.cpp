#include "generate/lift_seen.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/math.hpp"
#include "generate/lift_body.hpp"

namespace ks::lift {

Image inner_mask(const Image& mask, const LiftOptions& o) {
  Image inner = mask;
  const int r =
      std::max(1, int(std::lround(std::max(mask.width, mask.height) / o.outline_side_px)));
  cv::Mat m(mask.height, mask.width, CV_32FC1, const_cast<float*>(mask.data.data()));
  cv::Mat e(inner.height, inner.width, CV_32FC1, inner.data.data());
  cv::erode(m, e, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
  return inner;
}

SeenColour seen_colour(const Image& photo, const Image& inner, const Eigen::MatrixXd& V,
                       const Eigen::MatrixXd& normals, const MeshRenderOutput& depth,
                       const Camera& cam, const LiftOptions& o) {
  const long n = V.rows();
  const Eigen::Vector3d eye = cam.centre();
  SeenColour s;
  s.colour = Eigen::MatrixXd::Zero(n, 3);
  s.weight = Eigen::VectorXd::Zero(n);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) {
    const Eigen::Vector3d p = V.row(i).transpose();
    const Eigen::Vector3d c = cam.to_camera(p);
    if (c.z() <= 0) continue;
    const double cosv = -normals.row(i).dot((p - eye).normalized());
    if (cosv < o.visible_cos) continue;
    const Eigen::Vector2d uv = cam.project_camera(c);
    const int x = int(std::floor(uv.x())), y = int(std::floor(uv.y()));
    if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
    if (c.z() > depth.depth.at(x, y, 0) + o.depth_tolerance) continue;
    if (!in_mask(inner, uv.x(), uv.y())) continue;
    // Weight: how squarely the camera sees the surface.
    s.weight(i) = smoothstep(o.visible_cos, o.full_view_cos, cosv);
    s.colour.row(i) = sample_rgb(photo, uv.x(), uv.y()).transpose();
  }
  return s;
}

}  // namespace ks::lift
