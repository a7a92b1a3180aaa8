#include "reconstruct/mlp.hpp"

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

template <typename T>
void mlp_forward(const MlpT<T>& m, const Eigen::Ref<const typename MlpT<T>::Mat>& X,
                 MlpCacheT<T>& cache, typename MlpT<T>::Mat& Y) {
  const size_t L = m.W.size();
  cache.act.resize(L);
  cache.act[0] = X;
  for (size_t l = 0; l < L; ++l) {
    const auto& in = cache.act[l];
    if (l + 1 < L) {
      auto& out = cache.act[l + 1];
      out.resize(m.W[l].rows(), in.cols());
      out.noalias() = m.W[l] * in;
      out.colwise() += m.b[l];
      out = out.cwiseMax(T(0));
    } else {
      Y.resize(m.W[l].rows(), in.cols());
      Y.noalias() = m.W[l] * in;
      Y.colwise() += m.b[l];
    }
  }
}

template <typename T>
void mlp_backward(const MlpT<T>& m, const MlpCacheT<T>& cache,
                  const Eigen::Ref<const typename MlpT<T>::Mat>& dY, MlpGradsT<T>& g,
                  typename MlpT<T>::Mat* dX) {
  const int L = int(m.W.size());
  if (g.W.size() != m.W.size()) g.zero_like(m);
  // delta = dL/d(pre-activation output of layer l)
  typename MlpT<T>::Mat delta = dY;
  for (int l = L - 1; l >= 0; --l) {
    const auto& in = cache.act[l];
    g.W[l].noalias() += delta * in.transpose();
    g.b[l] += delta.rowwise().sum();
    if (l == 0 && !dX) break;
    typename MlpT<T>::Mat din;
    din.noalias() = m.W[l].transpose() * delta;
    if (l > 0) {
      // ReLU: in = max(pre, 0); gradient passes where in > 0.
      delta = (in.array() > T(0)).select(din, T(0));
    } else {
      *dX = std::move(din);
    }
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
