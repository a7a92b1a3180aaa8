#include "mesh/uv_atlas.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <numeric>
#include <string>
#include <utility>

#include "core/error.hpp"

namespace ks {
namespace {

bool power_of_two(int n) {
  return n > 0 && (n & (n - 1)) == 0;
}

void check(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F, const UvAtlasOptions& o) {
  if (V.rows() == 0 || F.rows() == 0 || V.cols() != 3 || F.cols() != 3)
    throw Error("uv atlas: the mesh has no vertices or no faces");
  if (F.minCoeff() < 0 || F.maxCoeff() >= V.rows())
    throw Error("uv atlas: a face names a vertex out of range (the mesh has " +
                std::to_string(V.rows()) + ")");
  if (!(o.max_normal_angle_deg > 0 && o.max_normal_angle_deg < 90))
    throw Error("uv atlas: max_normal_angle_deg must be in (0, 90), not " +
                std::to_string(o.max_normal_angle_deg));
  if (!(o.texels_per_edge > 0))
    throw Error("uv atlas: texels_per_edge must be > 0, not " + std::to_string(o.texels_per_edge));
  if (o.padding < 0) throw Error("uv atlas: padding must be >= 0");
  if (!power_of_two(o.min_size) || !power_of_two(o.max_size) || o.min_size > o.max_size)
    throw Error("uv atlas: min_size and max_size must be powers of two, min <= max (" +
                std::to_string(o.min_size) + ", " + std::to_string(o.max_size) + ")");
}

// For each face and each of its edges, the face across that edge (-1 on a border). Where more
// than two faces share an edge, one of the others.
std::vector<std::array<int, 3>> face_neighbours(const Eigen::MatrixXi& F) {
  const long M = F.rows();
  std::vector<std::pair<long long, int>> keyed;  // (edge key, face * 3 + edge)
  keyed.reserve(3 * size_t(M));
  for (long f = 0; f < M; ++f)
    for (int e = 0; e < 3; ++e) {
      const long long a = F(f, e), b = F(f, (e + 1) % 3);
      keyed.push_back({std::min(a, b) * (1LL << 32) + std::max(a, b), int(3 * f + e)});
    }
  std::sort(keyed.begin(), keyed.end());
  std::vector<std::array<int, 3>> nb(static_cast<size_t>(M), {-1, -1, -1});
  for (size_t i = 0; i < keyed.size();) {
    size_t j = i;
    while (j < keyed.size() && keyed[j].first == keyed[i].first) ++j;
    for (size_t k = i; k < j; ++k) {
      const int self = keyed[k].second, other = keyed[k + 1 < j ? k + 1 : i].second;
      if (other != self) nb[size_t(self / 3)][size_t(self % 3)] = other / 3;
    }
    i = j;
  }
  return nb;
}

struct Chart {
  std::vector<int> faces;
  Eigen::Vector3d t1, t2;          // the projection plane's axes (principal axes of the chart)
  Eigen::Vector2d lo, extent;      // the projected coordinates' minimum and extent (metres)
  int x = 0, y = 0, w = 0, h = 0;  // its rectangle in the texture (texels, gutter included)
};

// Grows the charts (breadth first across edges, within the normal cone of each seed).
std::vector<Chart> grow_charts(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F, double cos_max,
                               std::vector<int>& face_chart) {
  const long M = F.rows();
  std::vector<Eigen::Vector3d> n(static_cast<size_t>(M));
  std::vector<char> degenerate(static_cast<size_t>(M));
  for (long f = 0; f < M; ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Eigen::Vector3d x = (b - a).cross(c - a);
    const double len = x.norm();
    degenerate[size_t(f)] = !(len > 1e-14) || !std::isfinite(len);
    n[size_t(f)] = degenerate[size_t(f)] ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d(x / len);
  }
  const auto nb = face_neighbours(F);
  face_chart.assign(size_t(M), -1);
  std::vector<Chart> charts;
  std::deque<int> queue;
  for (long seed = 0; seed < M; ++seed) {
    if (face_chart[size_t(seed)] >= 0) continue;
    const int id = int(charts.size());
    charts.emplace_back();
    Chart& c = charts.back();
    const Eigen::Vector3d axis = n[size_t(seed)];
    face_chart[size_t(seed)] = id;
    queue.assign(1, int(seed));
    while (!queue.empty()) {
      const int f = queue.front();
      queue.pop_front();
      c.faces.push_back(f);
      for (int g : nb[size_t(f)])
        if (g >= 0 && face_chart[size_t(g)] < 0 &&
            (degenerate[size_t(g)] || n[size_t(g)].dot(axis) >= cos_max)) {
          face_chart[size_t(g)] = id;
          queue.push_back(g);
        }
    }
    // The plane: the seed's normal; within it, the principal axes of the chart's vertices.
    const Eigen::Vector3d helper =
        std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d a1 = axis.cross(helper).normalized(), a2 = axis.cross(a1);
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (int f : c.faces)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d p = V.row(F(f, k));
        mean += Eigen::Vector2d(p.dot(a1), p.dot(a2));
      }
    mean /= double(3 * c.faces.size());
    for (int f : c.faces)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d p = V.row(F(f, k));
        const Eigen::Vector2d d = Eigen::Vector2d(p.dot(a1), p.dot(a2)) - mean;
        cov += d * d.transpose();
      }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    Eigen::Vector2d major = es.eigenvectors().col(1);
    if (!major.allFinite() || major.norm() < 1e-12) major = Eigen::Vector2d::UnitX();
    major.normalize();
    c.t1 = major.x() * a1 + major.y() * a2;
    c.t2 = axis.cross(c.t1);
    Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
    for (int f : c.faces)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d p = V.row(F(f, k));
        const Eigen::Vector2d q(p.dot(c.t1), p.dot(c.t2));
        lo = lo.cwiseMin(q);
        hi = hi.cwiseMax(q);
      }
    // Landscape: shelves hold wide charts with the least waste.
    if (hi.y() - lo.y() > hi.x() - lo.x()) {
      const Eigen::Vector3d t1 = c.t1;
      c.t1 = c.t2;
      c.t2 = -t1;
      const Eigen::Vector2d l = lo, h = hi;
      lo = Eigen::Vector2d(l.y(), -h.x());
      hi = Eigen::Vector2d(h.y(), -l.x());
    }
    c.lo = lo;
    c.extent = hi - lo;
  }
  return charts;
}

double mean_edge_length(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F) {
  double sum = 0;
  for (long f = 0; f < F.rows(); ++f)
    for (int e = 0; e < 3; ++e) sum += (V.row(F(f, e)) - V.row(F(f, (e + 1) % 3))).norm();
  return sum / double(3 * F.rows());
}

// Shelf packing, tallest first, into a square of side `size`; false when the shelves overflow.
bool pack(std::vector<Chart>& charts, const std::vector<int>& order, int size) {
  int x = 0, y = 0, shelf = 0;
  for (int i : order) {
    Chart& c = charts[size_t(i)];
    if (c.w > size) return false;
    if (x + c.w > size) {
      x = 0;
      y += shelf;
      shelf = 0;
    }
    if (y + c.h > size) return false;
    c.x = x;
    c.y = y;
    x += c.w;
    shelf = std::max(shelf, c.h);
  }
  return true;
}

}  // namespace

UvAtlas build_uv_atlas(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F,
                       const UvAtlasOptions& opt) {
  check(V, F, opt);
  UvAtlas atlas;
  const double cos_max = std::cos(opt.max_normal_angle_deg * M_PI / 180.0);
  std::vector<Chart> charts = grow_charts(V, F, cos_max, atlas.face_chart);
  atlas.charts = int(charts.size());

  // Scale and size: the wanted scale; the smallest square that holds the charts at it, or, above
  // max_size, a scale lowered until they fit there; then the scale raised while they still fit.
  std::vector<int> order(charts.size());
  std::iota(order.begin(), order.end(), 0);
  auto lay_out = [&](double scale) {  // the rectangles at `scale`, tallest first; their area
    double area = 0;
    for (Chart& c : charts) {
      c.w = int(std::ceil(c.extent.x() * scale)) + 1 + 2 * opt.padding;
      c.h = int(std::ceil(c.extent.y() * scale)) + 1 + 2 * opt.padding;
      area += double(c.w) * c.h;
    }
    std::iota(order.begin(), order.end(), 0);  // the same order for the same scale, always
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      const int ha = charts[size_t(a)].h, hb = charts[size_t(b)].h;
      return ha != hb ? ha > hb : a < b;
    });
    return area;
  };
  double s = opt.texels_per_edge / std::max(mean_edge_length(V, F), 1e-9);
  int size = opt.min_size;
  for (int attempt = 0;; ++attempt) {
    const double area = lay_out(s);
    while (size < opt.max_size && double(size) * size < area) size *= 2;
    bool fits = pack(charts, order, size);
    while (!fits && size < opt.max_size) fits = pack(charts, order, size *= 2);
    if (fits) break;
    if (attempt > 200) throw Error("uv atlas: the charts do not fit in the largest texture");
    s *= 0.92;
  }
  if (opt.fill) {
    double lo = s, hi = 4 * s;
    for (int it = 0; it < 24; ++it) {
      const double mid = 0.5 * (lo + hi);
      lay_out(mid);
      (pack(charts, order, size) ? lo : hi) = mid;
    }
    s = lo;
    lay_out(s);
    if (!pack(charts, order, size)) throw Error("uv atlas: internal: the packing does not hold");
  }
  atlas.size = size;
  atlas.texels_per_metre = s;

  // Atlas vertices: one per (chart, mesh vertex).
  const long M = F.rows();
  atlas.faces.resize(M, 3);
  std::vector<int> stamp(size_t(V.rows()), -1), index(size_t(V.rows()), -1);
  for (int ci = 0; ci < int(charts.size()); ++ci) {
    const Chart& c = charts[size_t(ci)];
    for (int f : c.faces)
      for (int k = 0; k < 3; ++k) {
        const int v = F(f, k);
        if (stamp[size_t(v)] != ci) {
          stamp[size_t(v)] = ci;
          index[size_t(v)] = int(atlas.source.size());
          atlas.source.push_back(v);
          const Eigen::Vector3d p = V.row(v);
          const double x = c.x + opt.padding + 0.5 + (p.dot(c.t1) - c.lo.x()) * s;
          const double y = c.y + opt.padding + 0.5 + (p.dot(c.t2) - c.lo.y()) * s;
          atlas.uv.push_back(float(x / size));
          atlas.uv.push_back(float(y / size));
        }
        atlas.faces(f, k) = index[size_t(v)];
      }
  }
  return atlas;
}

}  // namespace ks
