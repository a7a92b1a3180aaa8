#include "mesh/morton.hpp"

#include <algorithm>
#include <cstdint>
#include <utility>

#include "core/error.hpp"

namespace ks {

namespace {

// The low 10 bits of v, spread to every third bit.
uint32_t spread3(uint32_t v) {
  v &= 0x3ffu;
  v = (v | (v << 16)) & 0x030000ffu;
  v = (v | (v << 8)) & 0x0300f00fu;
  v = (v | (v << 4)) & 0x030c30c3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

}  // namespace

std::vector<int> morton_order(const Eigen::MatrixXd& P, int bits) {
  if (P.rows() > 0 && P.cols() != 3) throw Error("morton_order: points must be n x 3");
  if (bits < 1 || bits > 10) throw Error("morton_order: bits must be in [1, 10]");
  const long n = P.rows();
  std::vector<std::pair<uint32_t, int>> keyed(static_cast<size_t>(n));
  if (n > 0) {
    const Eigen::RowVector3d lo = P.colwise().minCoeff(), hi = P.colwise().maxCoeff();
    const double cells = double(1 << bits);
    for (long i = 0; i < n; ++i) {
      uint32_t key = 0;
      for (int k = 0; k < 3; ++k) {
        const double extent = hi(k) - lo(k);
        const double t = extent > 0 ? (P(i, k) - lo(k)) / extent : 0.0;
        key |= spread3(uint32_t(std::clamp(t * cells, 0.0, cells - 1.0))) << k;
      }
      keyed[size_t(i)] = {key, int(i)};
    }
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> order(keyed.size());
  for (size_t j = 0; j < keyed.size(); ++j) order[j] = keyed[j].second;
  return order;
}

}  // namespace ks
