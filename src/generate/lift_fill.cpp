#include "generate/lift_fill.hpp"

#include <algorithm>
#include <cstdint>

namespace ks::lift {

namespace {
constexpr double kKept = 0.99;  // keep from which a vertex's colour is left as it is
}

int fill_by_propagation(const std::vector<std::vector<int>>& adj, const Eigen::VectorXd& weight,
                        double known_weight, Eigen::MatrixXd& colour) {
  const long n = colour.rows();
  std::vector<uint8_t> known(size_t(n), 0);
  for (long i = 0; i < n; ++i) known[size_t(i)] = weight(i) >= known_weight;
  int filled = 0;
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<int> front;
    for (long i = 0; i < n; ++i) {
      if (known[size_t(i)]) continue;
      for (int k : adj[size_t(i)])
        if (known[size_t(k)]) {
          front.push_back(int(i));
          break;
        }
    }
    std::vector<Eigen::Vector3d> val(front.size());
    for (size_t f = 0; f < front.size(); ++f) {
      Eigen::Vector3d s = Eigen::Vector3d::Zero();
      int c = 0;
      for (int k : adj[size_t(front[f])])
        if (known[size_t(k)]) {
          s += colour.row(k).transpose();
          ++c;
        }
      val[f] = s / std::max(1, c);
    }
    for (size_t f = 0; f < front.size(); ++f) {
      colour.row(front[f]) = val[f].transpose();
      known[size_t(front[f])] = 1;
      changed = true;
    }
    filled += int(front.size());
  }
  return filled;
}

void smooth_unseen(const std::vector<std::vector<int>>& adj, const Eigen::VectorXd& keep_w,
                   int passes, Eigen::MatrixXd& colour) {
  const long n = colour.rows();
  for (int pass = 0; pass < passes; ++pass) {
    Eigen::MatrixXd next = colour;
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) {
      const double keep = std::min(1.0, keep_w(i));
      if (keep >= kKept) continue;
      Eigen::Vector3d s = Eigen::Vector3d::Zero();
      for (int k : adj[size_t(i)]) s += colour.row(k).transpose();
      s /= std::max<size_t>(1, adj[size_t(i)].size());
      next.row(i) = (keep * colour.row(i).transpose() + (1 - keep) * s).transpose();
    }
    colour = next;
  }
}

}  // namespace ks::lift
