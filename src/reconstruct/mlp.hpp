#pragma once
// A small fully connected network evaluated on batches of points with Eigen matrix products.
// Points are columns: input X is in_dim x N (column-major, i.e. the point-major n x in_dim array
// the triplane writes). Hidden layers use ReLU; the output layer is linear (the decoders apply
// their own output activations, see decoder.hpp).
// The float instantiation uses AVX2+FMA kernels (mlp_kernels.hpp) when the CPU has them, unless
// KS_MLP_NO_AVX2=1 (their AVX-512 width, the same bits, where it has AVX-512 and
// KS_MLP_NO_AVX512 is not set); results then differ from the Eigen path by float rounding only.
// Either way they do not depend on the OpenMP thread count.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace ks {

template <typename T>
struct MlpT {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  using Vec = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  std::vector<Mat> W;  // layer l: out_l x in_l
  std::vector<Vec> b;  // out_l

  // dims = {in, hidden..., out}. He-uniform init for hidden layers; the last layer's weights are
  // scaled by last_scale (small outputs at the start) and its biases are zero.
  void init(const std::vector<int>& dims, uint64_t seed, T last_scale = T(0.01));
  int in_dim() const { return int(W.front().cols()); }
  int out_dim() const { return int(W.back().rows()); }
  size_t num_params() const;
  // Flattens parameters / gradients in a fixed order (W0, b0, W1, b1, ...): for the optimiser.
  void pack(std::vector<T>& out) const;
  void unpack(const std::vector<T>& in);
};

// Activations kept for the backward pass (reuse across iterations: no reallocation).
template <typename T>
struct MlpCacheT {
  // act[0] = the input (empty when the forward did not keep it), act[l] = output of layer l-1
  std::vector<typename MlpT<T>::Mat> act;
  typename MlpT<T>::Mat delta, delta_next;
};

template <typename T>
struct MlpGradsT {
  std::vector<typename MlpT<T>::Mat> W;
  std::vector<typename MlpT<T>::Vec> b;
  void zero_like(const MlpT<T>& m);
  void pack(std::vector<T>& out) const;
};

// Y = mlp(X); X: in x N (Map over caller memory), Y: out x N. keep_input = false: the cache
// keeps no copy of X (act[0] stays empty; X must then be contiguous), and mlp_backward must be
// given the same X, unchanged (the decoder, whose two MLPs read one feature matrix it keeps).
template <typename T>
void mlp_forward(const MlpT<T>& m, const Eigen::Ref<const typename MlpT<T>::Mat>& X,
                 MlpCacheT<T>& cache, typename MlpT<T>::Mat& Y, bool keep_input = true);
// Given dL/dY (out x N): accumulates weight/bias gradients into g and, if dX != nullptr, writes
// dL/dX (in x N), or with add_dx adds it to *dX (which must be in x N already; each element gets
// one addition of the finished dL/dX, as a separate sum would). X: the forward's input (in x N,
// contiguous) when the forward did not keep it, else nullptr.
template <typename T>
void mlp_backward(const MlpT<T>& m, const MlpCacheT<T>& cache,
                  const Eigen::Ref<const typename MlpT<T>::Mat>& dY, MlpGradsT<T>& g,
                  typename MlpT<T>::Mat* dX, const T* X = nullptr, bool add_dx = false);

// Two MLPs on one input X (in x N, contiguous, not kept: the decoder's two heads on the triplane
// features): the same results, bit for bit, as mlp_forward(a, X, cache_a, Ya, false) then
// mlp_forward(b, X, cache_b, Yb, false), with the AVX2 kernels a few points at a time through
// both, so that X is read from memory once instead of twice.
template <typename T>
void mlp_forward_pair(const MlpT<T>& a, const MlpT<T>& b,
                      const Eigen::Ref<const typename MlpT<T>::Mat>& X, MlpCacheT<T>& cache_a,
                      typename MlpT<T>::Mat& Ya, MlpCacheT<T>& cache_b, typename MlpT<T>::Mat& Yb);
// Their backward: the same results, bit for bit, as mlp_backward(a, cache_a, dYa, ga, &dX, X)
// then mlp_backward(b, cache_b, dYb, gb, &dX, X, true) (dX = a's input gradient plus b's), the
// AVX2 path again a few points at a time through both. X: the forwards' input.
template <typename T>
void mlp_backward_pair(const MlpT<T>& a, const MlpCacheT<T>& cache_a,
                       const Eigen::Ref<const typename MlpT<T>::Mat>& dYa, MlpGradsT<T>& ga,
                       const MlpT<T>& b, const MlpCacheT<T>& cache_b,
                       const Eigen::Ref<const typename MlpT<T>::Mat>& dYb, MlpGradsT<T>& gb,
                       typename MlpT<T>::Mat& dX, const T* X);

using Mlp = MlpT<float>;
using MlpCache = MlpCacheT<float>;
using MlpGrads = MlpGradsT<float>;

// The layers after the first of `count` float MLPs (of two layers or more), for a caller that
// computes their first layers itself (the decoder, in texel space: reconstruct/texel_layer0.hpp).
// AVX2 kernels only: throws ks::Error unless mlp_kernels::use_avx2().
// mlp_tail_buffers sizes a cache (act[0] empty) and Y for n points; the caller then writes the
// first layer's output after its ReLU to each cache's act[1], and mlp_forward_tail runs the
// layers from the second on: the results of mlp_forward from that act[1] on.
void mlp_tail_buffers(const Mlp& m, Eigen::Index n, MlpCache& cache, Mlp::Mat& Y);
void mlp_forward_tail(const Mlp* const* m, MlpCache* const* cache, Mlp::Mat* const* Y, int count);
// Their backward from dY (out x n each) to the first layer's output: the gradients of the later
// layers and of the first layer's bias accumulate into g as in mlp_backward (the first layer's
// weight gradient is left as it is), and the gradient of the first layer's pre-activation output
// (hidden x n, the ReLU's mask applied) is written to d0[q], leading dim ld0.
void mlp_backward_tail(const Mlp* const* m, const MlpCache* const* cache, const Mlp::Mat* const* dY,
                       MlpGrads* const* g, float* const* d0, std::ptrdiff_t ld0, int count);

}  // namespace ks
