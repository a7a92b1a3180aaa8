#include "reconstruct/visibility.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.hpp"

namespace ks {

int visible_points(const float* points, int n, const Camera& cam, const VisibilityOptions& o,
                   std::vector<int>* visible) {
  if (o.cell < 1 || o.reach < 0)
    throw Error("visible_points: the cell must be >= 1 pixel and the reach >= 0");
  const int cs = o.cell;
  const int cw = (cam.width + cs - 1) / cs, ch = (cam.height + cs - 1) / cs;
  const float inf = std::numeric_limits<float>::infinity();
  // Camera-space depth and cell of every point (-1: off the image or behind the camera).
  std::vector<float> depth(static_cast<size_t>(n));
  std::vector<int> cell(static_cast<size_t>(n));
  Eigen::Matrix3f R = cam.R.cast<float>();
  Eigen::Vector3f t = cam.t.cast<float>();
  const float fx = float(cam.fx), fy = float(cam.fy), cx = float(cam.cx), cy = float(cam.cy);
#pragma omp parallel for schedule(static) if (n > 16384)
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f p = R * Eigen::Vector3f(points[3 * size_t(i)], points[3 * size_t(i) + 1],
                                                  points[3 * size_t(i) + 2]) +
                              t;
    depth[size_t(i)] = p.z();
    cell[size_t(i)] = -1;
    if (!(p.z() > 1e-6f)) continue;
    const float u = fx * p.x() / p.z() + cx, v = fy * p.y() / p.z() + cy;
    if (!(u >= 0.f && v >= 0.f && u < float(cam.width) && v < float(cam.height))) continue;
    cell[size_t(i)] = std::min(ch - 1, int(v) / cs) * cw + std::min(cw - 1, int(u) / cs);
  }
  // The nearest depth in each cell, then the farthest of those around each cell.
  std::vector<float> nearest(size_t(cw) * ch, inf), row(nearest.size()), bound(nearest.size());
  for (int i = 0; i < n; ++i)
    if (cell[size_t(i)] >= 0)
      nearest[size_t(cell[size_t(i)])] =
          std::min(nearest[size_t(cell[size_t(i)])], depth[size_t(i)]);
  const int r = o.reach;
  for (int y = 0; y < ch; ++y)
    for (int x = 0; x < cw; ++x) {
      float m = -inf;
      for (int k = std::max(0, x - r); k <= std::min(cw - 1, x + r); ++k)
        m = std::max(m, nearest[size_t(y) * cw + k]);
      row[size_t(y) * cw + x] = m;
    }
  for (int y = 0; y < ch; ++y)
    for (int x = 0; x < cw; ++x) {
      float m = -inf;
      for (int k = std::max(0, y - r); k <= std::min(ch - 1, y + r); ++k)
        m = std::max(m, row[size_t(k) * cw + x]);
      bound[size_t(y) * cw + x] = m;
    }
  visible->clear();
  for (int i = 0; i < n; ++i) {
    const int c = cell[size_t(i)];
    if (c >= 0 && depth[size_t(i)] > bound[size_t(c)] + o.depth_margin) continue;
    visible->push_back(i);
  }
  return int(visible->size());
}

}  // namespace ks
