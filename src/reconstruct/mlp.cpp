#include "reconstruct/mlp.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace ks {

template <typename T>
void MlpT<T>::init(const std::vector<int>& dims, uint64_t seed, T last_scale) {
  W.clear();
  b.clear();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (size_t l = 0; l + 1 < dims.size(); ++l) {
    const int in = dims[l], out = dims[l + 1];
    const bool last = l + 2 == dims.size();
    const double bound = std::sqrt(6.0 / in) * (last ? double(last_scale) : 1.0);
    Mat w(out, in);
    for (int j = 0; j < in; ++j)
      for (int i = 0; i < out; ++i) w(i, j) = T(u(rng) * bound);
    W.push_back(w);
    b.push_back(Vec::Zero(out));
  }
}

template <typename T>
size_t MlpT<T>::num_params() const {
  size_t n = 0;
  for (size_t l = 0; l < W.size(); ++l) n += W[l].size() + b[l].size();
  return n;
}

template <typename T>
void MlpT<T>::pack(std::vector<T>& out) const {
  out.resize(num_params());
  size_t o = 0;
  for (size_t l = 0; l < W.size(); ++l) {
    std::copy(W[l].data(), W[l].data() + W[l].size(), out.begin() + o);
    o += W[l].size();
    std::copy(b[l].data(), b[l].data() + b[l].size(), out.begin() + o);
    o += b[l].size();
  }
}

template <typename T>
void MlpT<T>::unpack(const std::vector<T>& in) {
  size_t o = 0;
  for (size_t l = 0; l < W.size(); ++l) {
    std::copy(in.begin() + o, in.begin() + o + W[l].size(), W[l].data());
    o += W[l].size();
    std::copy(in.begin() + o, in.begin() + o + b[l].size(), b[l].data());
    o += b[l].size();
  }
}

template <typename T>
void MlpGradsT<T>::zero_like(const MlpT<T>& m) {
  W.resize(m.W.size());
  b.resize(m.b.size());
  for (size_t l = 0; l < m.W.size(); ++l) {
    W[l].setZero(m.W[l].rows(), m.W[l].cols());
    b[l].setZero(m.b[l].size());
  }
}

template <typename T>
void MlpGradsT<T>::pack(std::vector<T>& out) const {
  size_t n = 0;
  for (size_t l = 0; l < W.size(); ++l) n += W[l].size() + b[l].size();
  out.resize(n);
  size_t o = 0;
  for (size_t l = 0; l < W.size(); ++l) {
    std::copy(W[l].data(), W[l].data() + W[l].size(), out.begin() + o);
    o += W[l].size();
    std::copy(b[l].data(), b[l].data() + b[l].size(), out.begin() + o);
    o += b[l].size();
  }
}

namespace {
// Points are processed in column blocks, one OpenMP task per block; Eigen runs single-threaded
// inside (it does not nest its own threads in a parallel region). Per-block weight gradients are
// summed in block order, so results do not depend on the thread count.
constexpr Eigen::Index kBlock = 2048;
}  // namespace

template <typename T>
void mlp_forward(const MlpT<T>& m, const Eigen::Ref<const typename MlpT<T>::Mat>& X,
                 MlpCacheT<T>& cache, typename MlpT<T>::Mat& Y) {
  const size_t L = m.W.size();
  const Eigen::Index n = X.cols();
  cache.act.resize(L);
  cache.act[0] = X;
  for (size_t l = 1; l < L; ++l) cache.act[l].resize(m.W[l - 1].rows(), n);
  Y.resize(m.W[L - 1].rows(), n);
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (Eigen::Index bi = 0; bi < blocks; ++bi) {
    const Eigen::Index c0 = bi * kBlock, len = std::min(kBlock, n - c0);
    for (size_t l = 0; l < L; ++l) {
      auto in = cache.act[l].middleCols(c0, len);
      if (l + 1 < L) {
        auto out = cache.act[l + 1].middleCols(c0, len);
        out.noalias() = m.W[l] * in;
        out.colwise() += m.b[l];
        out = out.cwiseMax(T(0));
      } else {
        auto out = Y.middleCols(c0, len);
        out.noalias() = m.W[l] * in;
        out.colwise() += m.b[l];
      }
    }
  }
}

template <typename T>
void mlp_backward(const MlpT<T>& m, const MlpCacheT<T>& cache,
                  const Eigen::Ref<const typename MlpT<T>::Mat>& dY, MlpGradsT<T>& g,
                  typename MlpT<T>::Mat* dX) {
  using Mat = typename MlpT<T>::Mat;
  using Vec = typename MlpT<T>::Vec;
  const int L = int(m.W.size());
  if (g.W.size() != m.W.size()) g.zero_like(m);
  const Eigen::Index n = dY.cols();
  if (dX) dX->resize(m.W[0].cols(), n);
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
  std::vector<std::vector<Mat>> gW;
  gW.resize(size_t(blocks), std::vector<Mat>(size_t(L)));
  std::vector<std::vector<Vec>> gb;
  gb.resize(size_t(blocks), std::vector<Vec>(size_t(L)));
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (Eigen::Index bi = 0; bi < blocks; ++bi) {
    const Eigen::Index c0 = bi * kBlock, len = std::min(kBlock, n - c0);
    // delta = dL/d(pre-activation output of layer l)
    Mat delta = dY.middleCols(c0, len), din;
    for (int l = L - 1; l >= 0; --l) {
      const auto in = cache.act[size_t(l)].middleCols(c0, len);
      gW[size_t(bi)][size_t(l)].noalias() = delta * in.transpose();
      gb[size_t(bi)][size_t(l)] = delta.rowwise().sum();
      if (l == 0 && !dX) break;
      din.noalias() = m.W[size_t(l)].transpose() * delta;
      if (l > 0) {
        // ReLU: in = max(pre, 0); the gradient passes where in > 0.
        delta = (in.array() > T(0)).select(din, T(0));
      } else {
        dX->middleCols(c0, len) = din;
      }
    }
  }
  for (Eigen::Index bi = 0; bi < blocks; ++bi)
    for (int l = 0; l < L; ++l) {
      g.W[size_t(l)] += gW[size_t(bi)][size_t(l)];
      g.b[size_t(l)] += gb[size_t(bi)][size_t(l)];
    }
}

template struct MlpT<float>;
template struct MlpT<double>;
template struct MlpGradsT<float>;
template struct MlpGradsT<double>;
template void mlp_forward(const MlpT<float>&, const Eigen::Ref<const MlpT<float>::Mat>&,
                          MlpCacheT<float>&, MlpT<float>::Mat&);
template void mlp_forward(const MlpT<double>&, const Eigen::Ref<const MlpT<double>::Mat>&,
                          MlpCacheT<double>&, MlpT<double>::Mat&);
template void mlp_backward(const MlpT<float>&, const MlpCacheT<float>&,
                           const Eigen::Ref<const MlpT<float>::Mat>&, MlpGradsT<float>&,
                           MlpT<float>::Mat*);
template void mlp_backward(const MlpT<double>&, const MlpCacheT<double>&,
                           const Eigen::Ref<const MlpT<double>::Mat>&, MlpGradsT<double>&,
                           MlpT<double>::Mat*);

}  // namespace ks
