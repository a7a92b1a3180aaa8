#include "reconstruct/visibility.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.hpp"

namespace ks {

namespace {

// m(x, y) = max of v over the cells within r of (x, y) (a square window, clipped).
void window_max(const std::vector<float>& v, int cw, int ch, int r, std::vector<float>* tmp,
                std::vector<float>* m) {
  const float ninf = -std::numeric_limits<float>::infinity();
  tmp->resize(v.size());
  m->resize(v.size());
  for (int y = 0; y < ch; ++y)
    for (int x = 0; x < cw; ++x) {
      float a = ninf;
      for (int k = std::max(0, x - r); k <= std::min(cw - 1, x + r); ++k)
        a = std::max(a, v[size_t(y) * cw + k]);
      (*tmp)[size_t(y) * cw + x] = a;
    }
  for (int y = 0; y < ch; ++y)
    for (int x = 0; x < cw; ++x) {
      float a = ninf;
      for (int k = std::max(0, y - r); k <= std::min(ch - 1, y + r); ++k)
        a = std::max(a, (*tmp)[size_t(k) * cw + x]);
      (*m)[size_t(y) * cw + x] = a;
    }
}

}  // namespace

int visible_points(const float* points, const float* sigmas, int n, const Camera& cam,
                   const VisibilityOptions& o, std::vector<int>* visible) {
  if (o.cell < 1 || o.reach < 0)
    throw Error("visible_points: the cell must be >= 1 pixel and the reach >= 0");
  const int cs = o.cell;
  const int cw = (cam.width + cs - 1) / cs, ch = (cam.height + cs - 1) / cs;
  const float inf = std::numeric_limits<float>::infinity();
  // Camera-space depth, cell (-1: off the image or behind the camera) and the footprint's extra
  // reach in cells of every point.
  std::vector<float> depth(static_cast<size_t>(n));
  std::vector<int> cell(static_cast<size_t>(n)), extra(static_cast<size_t>(n), 0);
  const Eigen::Matrix3f R = cam.R.cast<float>();
  const Eigen::Vector3f t = cam.t.cast<float>();
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
    if (sigmas) {
      const float px = 3.f * sigmas[i] * std::max(fx, fy) / p.z();
      extra[size_t(i)] = int(std::min(1e6f, std::ceil(std::max(0.f, px) / float(cs))));
    }
  }
  // The nearest depth in each cell; then, for reaches reach + 0, 1, 2, 4, ... cells, the farthest
  // of those around each cell. A footprint wider than the last reach is never hidden.
  std::vector<float> nearest(size_t(cw) * ch, inf), tmp;
  for (int i = 0; i < n; ++i)
    if (cell[size_t(i)] >= 0)
      nearest[size_t(cell[size_t(i)])] =
          std::min(nearest[size_t(cell[size_t(i)])], depth[size_t(i)]);
  const std::vector<int> extras = {0, 1, 2, 4, 8, 16};
  std::vector<std::vector<float>> bound(extras.size());
  int max_extra = 0;
  for (int e : extras) max_extra = std::max(max_extra, e);
  std::vector<char> needed(extras.size(), 0);
  for (int i = 0; i < n; ++i) {
    if (cell[size_t(i)] < 0 || extra[size_t(i)] > max_extra) continue;
    size_t k = 0;
    while (extras[k] < extra[size_t(i)]) ++k;
    needed[k] = 1;
  }
  for (size_t k = 0; k < extras.size(); ++k)
    if (needed[k]) window_max(nearest, cw, ch, o.reach + extras[k], &tmp, &bound[k]);
  visible->clear();
  for (int i = 0; i < n; ++i) {
    const int c = cell[size_t(i)];
    if (c >= 0 && extra[size_t(i)] <= max_extra) {
      size_t k = 0;
      while (extras[k] < extra[size_t(i)]) ++k;
      if (depth[size_t(i)] > bound[k][size_t(c)] + o.depth_margin) continue;
    }
    visible->push_back(i);
  }
  return int(visible->size());
}

}  // namespace ks
