#include "fit/silhouette.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace ks::fit {

namespace {

cv::Mat binary(const Image& mask) {
  cv::Mat b(mask.height, mask.width, CV_8UC1);
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x) b.at<uint8_t>(y, x) = mask.at(x, y, 0) >= 0.5f ? 255 : 0;
  return b;
}

}  // namespace

DistanceField outside_distance(const Image& mask) {
  DistanceField f;
  f.width = mask.width;
  f.height = mask.height;
  cv::Mat outside;
  cv::bitwise_not(binary(mask), outside);  // nonzero outside the mask
  cv::Mat dist;
  cv::distanceTransform(outside, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  f.d.assign(dist.begin<float>(), dist.end<float>());
  return f;
}

double DistanceField::sample(double u, double v, double* du, double* dv) const {
  // Pixel (i, j)'s value sits at (i + 0.5, j + 0.5).
  double x = u - 0.5, y = v - 0.5;
  // Outside the image: clamp, then add the distance beyond the border (gradient pointing out).
  double extra = 0, ex_du = 0, ex_dv = 0;
  const double xmax = width - 1, ymax = height - 1;
  if (x < 0) {
    extra += -x;
    ex_du = -1;
    x = 0;
  } else if (x > xmax) {
    extra += x - xmax;
    ex_du = 1;
    x = xmax;
  }
  if (y < 0) {
    extra += -y;
    ex_dv = -1;
    y = 0;
  } else if (y > ymax) {
    extra += y - ymax;
    ex_dv = 1;
    y = ymax;
  }
  const int x0 = std::min(int(std::floor(x)), std::max(0, width - 2));
  const int y0 = std::min(int(std::floor(y)), std::max(0, height - 2));
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int xx, int yy) { return double(d[size_t(yy) * width + xx]); };
  const double a = at(x0, y0), b = at(x1, y0), c = at(x0, y1), e = at(x1, y1);
  const double val = (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * c + fx * e);
  // Along an axis clamped to the border the field is constant: the gradient there is the
  // distance beyond the border's alone.
  if (du) *du = ex_du != 0 ? ex_du : (1 - fy) * (b - a) + fy * (e - c);
  if (dv) *dv = ex_dv != 0 ? ex_dv : (1 - fx) * (c - a) + fx * (e - b);
  return val + extra;
}

std::vector<Eigen::Vector2d> outline_samples(const Image& mask, double spacing, int max_points) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(binary(mask), contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
  size_t total = 0;
  for (const auto& c : contours) total += c.size();
  if (total == 0) return {};
  double step = std::max(1.0, spacing);
  if (max_points > 0) step = std::max(step, double(total) / max_points);
  std::vector<Eigen::Vector2d> out;
  for (const auto& c : contours) {
    if (c.size() < 8) continue;  // specks
    for (double s = 0; s < double(c.size()); s += step) {
      const cv::Point& p = c[size_t(s)];
      out.emplace_back(p.x + 0.5, p.y + 0.5);
    }
  }
  return out;
}

std::vector<uint8_t> outline_pixels(const Image& mask) {
  const int W = mask.width, H = mask.height;
  std::vector<uint8_t> out(size_t(W) * H, 0);
  auto in = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < W && y < H && mask.at(x, y, 0) >= 0.5f;
  };
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (in(x, y) && (!in(x - 1, y) || !in(x + 1, y) || !in(x, y - 1) || !in(x, y + 1)))
        out[size_t(y) * W + x] = 1;
  return out;
}

std::vector<RimVertex> rim_vertices(const Eigen::MatrixXd& V, const std::vector<int>* candidates,
                                    const Camera& cam, const MeshRenderOutput& r,
                                    double depth_tolerance) {
  const std::vector<uint8_t> edge = outline_pixels(r.mask);
  const int n = candidates ? int(candidates->size()) : int(V.rows());
  std::vector<RimVertex> out;
  for (int m = 0; m < n; ++m) {
    const int i = candidates ? (*candidates)[size_t(m)] : m;
    const Eigen::Vector3d c = cam.to_camera(V.row(i).transpose());
    if (c.z() <= 0) continue;
    const Eigen::Vector2d uv = cam.project_camera(c);
    const int px = int(std::floor(uv.x())), py = int(std::floor(uv.y()));
    bool near = false, visible = false;
    for (int dy = -1; dy <= 1 && !near; ++dy)
      for (int dx = -1; dx <= 1 && !near; ++dx) {
        const int xx = px + dx, yy = py + dy;
        if (xx < 0 || yy < 0 || xx >= r.width || yy >= r.height) continue;
        const size_t p = size_t(yy) * r.width + xx;
        if (!edge[p]) continue;
        near = true;
        visible = c.z() <= r.depth.data[p] + depth_tolerance;
      }
    if (near && visible) out.push_back({i, m, uv, c.z()});
  }
  return out;
}

}  // namespace ks::fit
