#include "reconstruct/mlp.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <new>
#include <random>
#include <type_traits>

#include "core/error.hpp"
#include "reconstruct/mlp_kernels.hpp"

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
// The SIMD path (AVX2 or AVX-512 kernels) walks a block in sub-blocks of this many points through
// all layers, so that a sub-block's activations and deltas stay in L1/L2 (a multiple of the
// kernels' 6 / 12 points).
constexpr Eigen::Index kSub = 48;

namespace mk = mlp_kernels;

// Weights with rows padded to a multiple of 8 (zero rows), W[l] as stored (out x in) or transposed
// (in x out), and padded biases: the kernels' operand layout. Re-packed on every call (tens of KB).
struct Packed {
  std::vector<float> data;
  std::vector<size_t> w, b;  // per-layer offsets into data
  void pack(const MlpT<float>& m, bool transposed) {
    const size_t L = m.W.size();
    w.resize(L);
    b.resize(L);
    size_t total = 0;
    for (size_t l = 0; l < L; ++l) {
      const int rows = int(transposed ? m.W[l].cols() : m.W[l].rows());
      const int cols = int(transposed ? m.W[l].rows() : m.W[l].cols());
      w[l] = total;
      total += size_t(mk::pad8(rows)) * size_t(cols);
      b[l] = total;
      total += size_t(mk::pad8(rows));
    }
    data.assign(total, 0.f);
    for (size_t l = 0; l < L; ++l) {
      const auto& W = m.W[l];
      const int out = int(W.rows()), in = int(W.cols());
      if (!transposed) {
        const size_t ld = size_t(mk::pad8(out));
        for (int j = 0; j < in; ++j)
          for (int i = 0; i < out; ++i) data[w[l] + size_t(j) * ld + size_t(i)] = W(i, j);
        for (int i = 0; i < out; ++i) data[b[l] + size_t(i)] = m.b[l](i);
      } else {
        const size_t ld = size_t(mk::pad8(in));
        for (int i = 0; i < out; ++i)
          for (int j = 0; j < in; ++j) data[w[l] + size_t(i) * ld + size_t(j)] = W(i, j);
      }
    }
  }
};

// Sizes the activation cache (act[0] = input copy, empty when the input is not kept,
// act[l] = layer l-1's output) and Y for a forward pass over X's columns.
template <typename T>
void size_forward_buffers(const MlpT<T>& m, const Eigen::Ref<const typename MlpT<T>::Mat>& X,
                          bool keep_input, MlpCacheT<T>& cache, typename MlpT<T>::Mat& Y) {
  const size_t L = m.W.size();
  if (!keep_input && X.outerStride() != X.rows())
    throw Error("mlp_forward: an input the cache does not keep must be contiguous");
  cache.act.resize(L);
  if (keep_input)
    cache.act[0].resize(X.rows(), X.cols());
  else
    cache.act[0].resize(X.rows(), 0);
  for (size_t l = 1; l < L; ++l) cache.act[l].resize(m.W[l - 1].rows(), X.cols());
  Y.resize(m.W[L - 1].rows(), X.cols());
}

// One MLP of a forward over a shared input: the MLP, its cache and its output.
struct ForwardJob {
  const MlpT<float>* m;
  MlpCacheT<float>* cache;
  MlpT<float>::Mat* Y;
};

// The MLPs of `jobs` on one input X (n points), a sub-block of points through each in turn (so
// that the later ones read the sub-block's input from L1); each job's results are those of a
// forward of its MLP alone. first > 0: only the layers from `first` on, each job's input being
// its cache.act[first] (filled by the caller; X is then unused and the buffers already sized).
void forward_simd(const ForwardJob* jobs, int count, const Eigen::Ref<const MlpT<float>::Mat>* X,
                  Eigen::Index n, bool keep_input, int first = 0) {
  // Caller-thread scratch, reused across calls; the OpenMP workers use it through this reference
  // (naming the thread_local inside the parallel region would give each worker its own copy).
  static thread_local std::vector<Packed> packed;
  std::vector<Packed>& pks = packed;
  if (int(pks.size()) < count) pks.resize(size_t(count));
  for (int q = 0; q < count; ++q) {
    if (first == 0)
      size_forward_buffers<float>(*jobs[q].m, *X, keep_input, *jobs[q].cache, *jobs[q].Y);
    pks[size_t(q)].pack(*jobs[q].m, false);
  }
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
#pragma omp parallel for schedule(dynamic, 1) if (blocks > 1)
  for (Eigen::Index bi = 0; bi < blocks; ++bi) {
    const Eigen::Index c0 = bi * kBlock, c1 = std::min(c0 + kBlock, n);
    for (Eigen::Index s0 = c0; s0 < c1; s0 += kSub) {
      const Eigen::Index len = std::min(kSub, c1 - s0);
      for (int q = 0; q < count; ++q) {
        const MlpT<float>& m = *jobs[q].m;
        MlpCacheT<float>& cache = *jobs[q].cache;
        MlpT<float>::Mat& Y = *jobs[q].Y;
        const Packed& pk = pks[size_t(q)];
        const size_t L = m.W.size();
        // The input is kept for the backward pass (unless the caller keeps it); copied here, a
        // sub-block at a time, so the first layer reads it from L1.
        if (first == 0 && keep_input && X->outerStride() == X->rows())
          std::memcpy(cache.act[0].data() + s0 * X->rows(), X->data() + s0 * X->rows(),
                      sizeof(float) * size_t(len) * size_t(X->rows()));
        else if (first == 0 && keep_input)
          cache.act[0].middleCols(s0, len) = X->middleCols(s0, len);
        for (size_t l = size_t(first); l < L; ++l) {
          const int in = int(m.W[l].cols()), out = int(m.W[l].rows());
          const bool last = l + 1 == L;
          float* dst = last ? Y.data() + s0 * out : cache.act[l + 1].data() + s0 * out;
          const float* src = l == 0 && !keep_input ? X->data() : cache.act[l].data();
          mk::gemm_cols(pk.data.data() + pk.w[l], out, in, src + s0 * in, in, int(len), dst, out,
                        last ? mk::Epilogue::kBias : mk::Epilogue::kBiasRelu,
                        pk.data.data() + pk.b[l], nullptr, 0);
        }
      }
    }
  }
}

// One MLP of a backward over a shared input: its forward's cache, the gradient of its output, its
// gradients, whether it adds its input gradient to dX (else writes it), and the layout of its
// per-block gradient partials (filled by backward_simd).
struct BackwardJob {
  BackwardJob(const MlpT<float>* m_, const MlpCacheT<float>* cache_,
              const Eigen::Ref<const MlpT<float>::Mat>* dY_, MlpGradsT<float>* g_, bool add_dx_)
      : m(m_), cache(cache_), dY(dY_), g(g_), add_dx(add_dx_) {}
  const MlpT<float>* m;
  const MlpCacheT<float>* cache;
  const Eigen::Ref<const MlpT<float>::Mat>* dY;
  MlpGradsT<float>* g;
  bool add_dx;
  // stop > 0: the layers from `stop` on only; the gradient of layer stop - 1's pre-activation
  // output (after the ReLU's mask) goes to d0 (leading dim ld0), its row sums to that layer's
  // bias gradient, and that layer's weight gradient stays zero.
  int stop = 0;
  float* d0 = nullptr;
  std::ptrdiff_t ld0 = 0;
  // Layer l's dW partial at gw[l], db at gbo[l]; trans[l]: accumulated as dW^T.
  std::vector<size_t> gw, gbo;
  std::vector<char> trans;
  size_t per_block = 0;
};

// The MLPs of `jobs`, whose forwards read the same input X0, a sub-block of points through each
// in turn (their input gradients are written / added to dX in job order); each job's gradients
// are those of a backward of its MLP alone.
void backward_simd(BackwardJob* jobs, int count, MlpT<float>::Mat* dX, const float* X0) {
  const Eigen::Index n = (*jobs[0].dY).cols();
  // Caller-thread scratch (see forward_simd): transposed weights for din = W^T delta, and the
  // per-block gradient partials.
  static thread_local std::vector<Packed> packed;
  static thread_local std::vector<std::vector<float>> partials;
  std::vector<Packed>& pks = packed;
  std::vector<std::vector<float>>& parts = partials;
  if (int(pks.size()) < count) pks.resize(size_t(count));
  if (int(parts.size()) < count) parts.resize(size_t(count));
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
  int maxdim = 0;
  for (int q = 0; q < count; ++q) {
    BackwardJob& J = jobs[q];
    const MlpT<float>& m = *J.m;
    const int L = int(m.W.size());
    if (J.g->W.size() != m.W.size()) J.g->zero_like(m);
    if (dX && !J.add_dx) dX->resize(m.W[0].cols(), n);
    pks[size_t(q)].pack(m, true);
    // Rows padded. A layer whose output count pads badly (9 or 3 outputs from 32 or 64 inputs)
    // accumulates dW^T = in delta^T instead (vectors along the inputs; pad8(in) x out).
    J.gw.assign(size_t(L), 0), J.gbo.assign(size_t(L), 0), J.trans.assign(size_t(L), 0);
    J.per_block = 0;
    for (int l = 0; l < L; ++l) {
      const int out = int(m.W[size_t(l)].rows()), in = int(m.W[size_t(l)].cols());
      const size_t normal = size_t(mk::pad8(out)) * size_t(in);
      const size_t transposed = size_t(mk::pad8(in)) * size_t(out);
      J.trans[size_t(l)] = transposed < normal;
      J.gw[size_t(l)] = J.per_block;
      J.per_block += std::min(normal, transposed);
      J.gbo[size_t(l)] = J.per_block;
      J.per_block += size_t(mk::pad8(out));
      maxdim = std::max(maxdim, in);
    }
    parts[size_t(q)].resize(size_t(blocks) * J.per_block);
  }
#pragma omp parallel for schedule(dynamic, 1) if (blocks > 1)
  for (Eigen::Index bi = 0; bi < blocks; ++bi) {
    for (int q = 0; q < count; ++q) {
      float* pb = parts[size_t(q)].data() + size_t(bi) * jobs[q].per_block;
      std::fill(pb, pb + jobs[q].per_block, 0.f);
    }
    static thread_local std::vector<float> scratch;
    scratch.resize(2 * size_t(kSub) * size_t(maxdim));
    const Eigen::Index c0 = bi * kBlock, c1 = std::min(c0 + kBlock, n);
    for (Eigen::Index s0 = c0; s0 < c1; s0 += kSub) {
      const int len = int(std::min(kSub, c1 - s0));
      for (int q = 0; q < count; ++q) {
        const BackwardJob& J = jobs[q];
        const MlpT<float>& m = *J.m;
        const Packed& pk = pks[size_t(q)];
        float* pb = parts[size_t(q)].data() + size_t(bi) * J.per_block;
        const int L = int(m.W.size());
        const Eigen::Index ldy = J.dY->outerStride();
        // delta = dL/d(pre-activation output of layer l), leading dim ld.
        const float* delta = J.dY->data() + s0 * ldy;
        Eigen::Index ld = ldy;
        for (int l = L - 1; l >= J.stop; --l) {
          const int in = int(m.W[size_t(l)].cols()), out = int(m.W[size_t(l)].rows());
          const float* act = (l == 0 ? X0 : J.cache->act[size_t(l)].data()) + s0 * in;
          if (J.trans[size_t(l)]) {
            mk::outer_acc(act, in, in, delta, ld, out, len, pb + J.gw[size_t(l)], nullptr);
            mk::rowsum_acc(delta, ld, out, len, pb + J.gbo[size_t(l)]);
          } else {
            mk::outer_acc(delta, ld, out, act, in, in, len, pb + J.gw[size_t(l)],
                          pb + J.gbo[size_t(l)]);
          }
          if (l == 0 && !dX) break;
          const bool to_d0 = J.stop > 0 && l == J.stop;
          float* dst = to_d0   ? J.d0 + s0 * J.ld0
                       : l > 0 ? scratch.data() + size_t(l % 2) * size_t(kSub) * size_t(maxdim)
                               : dX->data() + s0 * in;
          const Eigen::Index ldd = to_d0 ? J.ld0 : in;
          // l > 0: ReLU backward, the gradient passes where the layer's output act > 0.
          mk::gemm_cols(
              pk.data.data() + pk.w[size_t(l)], in, out, delta, ld, len, dst, ldd,
              l > 0 ? mk::Epilogue::kMask : (J.add_dx ? mk::Epilogue::kAdd : mk::Epilogue::kNone),
              nullptr, l > 0 ? act : nullptr, in);
          if (to_d0) {
            mk::rowsum_acc(dst, ldd, in, len, pb + J.gbo[size_t(l - 1)]);
            break;
          }
          delta = dst;
          ld = ldd;
        }
      }
    }
  }
  // Sum the partials in block order (per element, independent of the thread count).
  for (int q = 0; q < count; ++q) {
    const BackwardJob& J = jobs[q];
    const std::vector<float>& part = parts[size_t(q)];
    for (int l = 0; l < int(J.m->W.size()); ++l) {
      auto& GW = J.g->W[size_t(l)];
      auto& GB = J.g->b[size_t(l)];
      const int out = int(GW.rows()), in = int(GW.cols());
      const bool tr = J.trans[size_t(l)] != 0;
      // Element (i, j) of this layer's partial: dW at i * si + j * sj, db at gbo + i.
      const size_t si = tr ? size_t(mk::pad8(in)) : 1, sj = tr ? 1 : size_t(mk::pad8(out));
#pragma omp parallel for schedule(static) if (size_t(blocks) * size_t(out) * size_t(in) > 100000)
      for (int j = 0; j <= in; ++j) {  // j == in: the bias
        float* dst = j < in ? GW.data() + size_t(j) * size_t(out) : GB.data();
        const size_t off = j < in ? J.gw[size_t(l)] + size_t(j) * sj : J.gbo[size_t(l)];
        const size_t step = j < in ? si : 1;
        for (Eigen::Index bi = 0; bi < blocks; ++bi) {
          const float* src = part.data() + size_t(bi) * J.per_block + off;
          for (int i = 0; i < out; ++i) dst[i] += src[size_t(i) * step];
        }
      }
    }
  }
}

}  // namespace

template <typename T>
void mlp_forward(const MlpT<T>& m, const Eigen::Ref<const typename MlpT<T>::Mat>& X,
                 MlpCacheT<T>& cache, typename MlpT<T>::Mat& Y, bool keep_input) {
  if constexpr (std::is_same_v<T, float>) {
    if (mk::use_avx2()) {
      const ForwardJob job{&m, &cache, &Y};
      forward_simd(&job, 1, &X, X.cols(), keep_input);
      return;
    }
  }
  const size_t L = m.W.size();
  const Eigen::Index n = X.cols();
  size_forward_buffers<T>(m, X, keep_input, cache, Y);
  using Mat = typename MlpT<T>::Mat;
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (Eigen::Index bi = 0; bi < blocks; ++bi) {
    const Eigen::Index c0 = bi * kBlock, len = std::min(kBlock, n - c0);
    if (keep_input) cache.act[0].middleCols(c0, len) = X.middleCols(c0, len);
    for (size_t l = 0; l < L; ++l) {
      const Eigen::Map<const Mat> A(l == 0 && !keep_input ? X.data() : cache.act[l].data(),
                                    m.W[l].cols(), n);
      const auto in = A.middleCols(c0, len);
      if (l + 1 < L) {
        auto out = cache.act[l + 1].middleCols(c0, len);
        out.noalias() = m.W[l] * in;
        out = (out.colwise() + m.b[l]).cwiseMax(T(0));
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
                  typename MlpT<T>::Mat* dX, const T* X, bool add_dx) {
  // The first layer's input: the forward's copy, or the caller's X when it kept none.
  if (m.W.empty() || cache.act.size() != m.W.size())
    throw Error("mlp_backward: the cache is not from a forward pass of this MLP");
  if (!X && cache.act[0].cols() != dY.cols())
    throw Error("mlp_backward: the forward kept no input and none was given");
  const T* X0 = X ? X : cache.act[0].data();
  if (dX && add_dx && (dX->rows() != m.W[0].cols() || dX->cols() != dY.cols()))
    throw Error("mlp_backward: the gradient to add to has the wrong shape");
  if constexpr (std::is_same_v<T, float>) {
    if (mk::use_avx2()) {
      BackwardJob job(&m, &cache, &dY, &g, add_dx);
      backward_simd(&job, 1, dX, X0);
      return;
    }
  }
  using Mat = typename MlpT<T>::Mat;
  using Vec = typename MlpT<T>::Vec;
  using StridedMap = Eigen::Map<const Mat, 0, Eigen::OuterStride<>>;
  const int L = int(m.W.size());
  if (g.W.size() != m.W.size()) g.zero_like(m);
  const Eigen::Index n = dY.cols();
  if (dX && !add_dx) dX->resize(m.W[0].cols(), n);
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
  // Per-block gradient partials in one flat buffer reused across calls (caller thread; the
  // workers use it through the reference): layer l's dW (out x in) at ow[l], db at ob[l].
  std::vector<size_t> ow(static_cast<size_t>(L)), ob(static_cast<size_t>(L));
  size_t per_block = 0;
  Eigen::Index maxdim = 0;
  for (int l = 0; l < L; ++l) {
    ow[size_t(l)] = per_block;
    per_block += size_t(m.W[size_t(l)].size());
    ob[size_t(l)] = per_block;
    per_block += size_t(m.W[size_t(l)].rows());
    maxdim = std::max(maxdim, m.W[size_t(l)].cols());
  }
  static thread_local std::vector<T> partials;
  std::vector<T>& part = partials;
  part.resize(size_t(blocks) * per_block);
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (Eigen::Index bi = 0; bi < blocks; ++bi) {
    const Eigen::Index c0 = bi * kBlock, len = std::min(kBlock, n - c0);
    T* pb = part.data() + size_t(bi) * per_block;
    // Two delta buffers per worker thread, reused across blocks and calls.
    static thread_local std::vector<T> scratch;
    scratch.resize(2 * size_t(maxdim) * size_t(kBlock));
    T* bufs[2] = {scratch.data(), scratch.data() + size_t(maxdim) * size_t(kBlock)};
    // delta = dL/d(pre-activation output of layer l)
    StridedMap delta(dY.data() + c0 * dY.outerStride(), dY.rows(), len,
                     Eigen::OuterStride<>(dY.outerStride()));
    for (int l = L - 1; l >= 0; --l) {
      const auto& W = m.W[size_t(l)];
      const Eigen::Map<const Mat> A(l == 0 ? X0 : cache.act[size_t(l)].data(), W.cols(), n);
      const auto in = A.middleCols(c0, len);
      Eigen::Map<Mat>(pb + ow[size_t(l)], W.rows(), W.cols()).noalias() = delta * in.transpose();
      Eigen::Map<Vec> gb(pb + ob[size_t(l)], W.rows());
      gb.setZero();
      for (Eigen::Index p = 0; p < len; ++p) gb += delta.col(p);  // row sums, points in order
      if (l == 0) {
        if (dX && add_dx) {
          // The product first (in the delta buffer not in use), then one addition.
          Eigen::Map<Mat> prod(delta.data() == bufs[0] ? bufs[1] : bufs[0], W.cols(), len);
          prod.noalias() = W.transpose() * delta;
          dX->middleCols(c0, len) += prod;
        } else if (dX) {
          dX->middleCols(c0, len).noalias() = W.transpose() * delta;
        }
        break;
      }
      T* dst = bufs[l % 2];
      Eigen::Map<Mat> din(dst, W.cols(), len);
      din.noalias() = W.transpose() * delta;
      // ReLU: in = max(pre, 0); the gradient passes where in > 0 (in is contiguous).
      const T* a = in.data();
      const size_t cnt = size_t(din.size());
      for (size_t i = 0; i < cnt; ++i) dst[i] = a[i] > T(0) ? dst[i] : T(0);
      new (&delta) StridedMap(dst, W.cols(), len, Eigen::OuterStride<>(W.cols()));
    }
  }
  // Sum the partials in block order (per element, independent of the thread count).
  for (int l = 0; l < L; ++l) {
    auto& GW = g.W[size_t(l)];
    auto& GB = g.b[size_t(l)];
    for (Eigen::Index bi = 0; bi < blocks; ++bi) {
      const T* pb = part.data() + size_t(bi) * per_block;
      GW += Eigen::Map<const Mat>(pb + ow[size_t(l)], GW.rows(), GW.cols());
      GB += Eigen::Map<const Vec>(pb + ob[size_t(l)], GB.size());
    }
  }
}

template struct MlpT<float>;
template struct MlpT<double>;
template struct MlpGradsT<float>;
template struct MlpGradsT<double>;
template <typename T>
void mlp_forward_pair(const MlpT<T>& a, const MlpT<T>& b,
                      const Eigen::Ref<const typename MlpT<T>::Mat>& X, MlpCacheT<T>& cache_a,
                      typename MlpT<T>::Mat& Ya, MlpCacheT<T>& cache_b, typename MlpT<T>::Mat& Yb) {
  if constexpr (std::is_same_v<T, float>) {
    if (mk::use_avx2()) {
      const ForwardJob jobs[2] = {{&a, &cache_a, &Ya}, {&b, &cache_b, &Yb}};
      forward_simd(jobs, 2, &X, X.cols(), false);
      return;
    }
  }
  mlp_forward(a, X, cache_a, Ya, false);
  mlp_forward(b, X, cache_b, Yb, false);
}

template <typename T>
void mlp_backward_pair(const MlpT<T>& a, const MlpCacheT<T>& cache_a,
                       const Eigen::Ref<const typename MlpT<T>::Mat>& dYa, MlpGradsT<T>& ga,
                       const MlpT<T>& b, const MlpCacheT<T>& cache_b,
                       const Eigen::Ref<const typename MlpT<T>::Mat>& dYb, MlpGradsT<T>& gb,
                       typename MlpT<T>::Mat& dX, const T* X) {
  if constexpr (std::is_same_v<T, float>) {
    if (mk::use_avx2()) {
      if (a.W.empty() || b.W.empty() || cache_a.act.size() != a.W.size() ||
          cache_b.act.size() != b.W.size())
        throw Error("mlp_backward_pair: a cache is not from a forward pass of its MLP");
      if (!X || dYa.cols() != dYb.cols() || a.W[0].cols() != b.W[0].cols())
        throw Error("mlp_backward_pair: the two MLPs do not share one input");
      BackwardJob jobs[2] = {BackwardJob(&a, &cache_a, &dYa, &ga, false),
                             BackwardJob(&b, &cache_b, &dYb, &gb, true)};
      backward_simd(jobs, 2, &dX, X);
      return;
    }
  }
  mlp_backward(a, cache_a, dYa, ga, &dX, X);
  mlp_backward(b, cache_b, dYb, gb, &dX, X, true);
}

void mlp_tail_buffers(const Mlp& m, Eigen::Index n, MlpCache& cache, Mlp::Mat& Y) {
  const size_t L = m.W.size();
  if (L < 2) throw Error("mlp_tail_buffers: the MLP has one layer, no tail");
  cache.act.resize(L);
  cache.act[0].resize(m.W[0].cols(), 0);
  for (size_t l = 1; l < L; ++l) cache.act[l].resize(m.W[l - 1].rows(), n);
  Y.resize(m.W[L - 1].rows(), n);
}

void mlp_forward_tail(const Mlp* const* m, MlpCache* const* cache, Mlp::Mat* const* Y, int count) {
  if (!mk::use_avx2()) throw Error("mlp_forward_tail: needs the AVX2 kernels");
  std::vector<ForwardJob> jobs;
  for (int q = 0; q < count; ++q) {
    if (m[q]->W.size() < 2 || cache[q]->act.size() != m[q]->W.size() ||
        cache[q]->act[1].cols() != Y[q]->cols())
      throw Error("mlp_forward_tail: buffers not sized by mlp_tail_buffers for this MLP");
    jobs.push_back({m[q], cache[q], Y[q]});
  }
  if (count > 0) forward_simd(jobs.data(), count, nullptr, Y[0]->cols(), false, 1);
}

void mlp_backward_tail(const Mlp* const* m, const MlpCache* const* cache, const Mlp::Mat* const* dY,
                       MlpGrads* const* g, float* const* d0, std::ptrdiff_t ld0, int count) {
  if (!mk::use_avx2()) throw Error("mlp_backward_tail: needs the AVX2 kernels");
  std::vector<Eigen::Ref<const Mlp::Mat>> refs;
  refs.reserve(size_t(count));
  std::vector<BackwardJob> jobs;
  for (int q = 0; q < count; ++q) {
    if (m[q]->W.size() < 2 || cache[q]->act.size() != m[q]->W.size() ||
        cache[q]->act[1].cols() != dY[q]->cols())
      throw Error("mlp_backward_tail: the cache is not from mlp_forward_tail of this MLP");
    refs.emplace_back(*dY[q]);
    BackwardJob J(m[q], cache[q], &refs.back(), g[q], false);
    J.stop = 1, J.d0 = d0[q], J.ld0 = ld0;
    jobs.push_back(J);
  }
  if (count > 0) backward_simd(jobs.data(), count, nullptr, nullptr);
}

template void mlp_forward(const MlpT<float>&, const Eigen::Ref<const MlpT<float>::Mat>&,
                          MlpCacheT<float>&, MlpT<float>::Mat&, bool);
template void mlp_forward(const MlpT<double>&, const Eigen::Ref<const MlpT<double>::Mat>&,
                          MlpCacheT<double>&, MlpT<double>::Mat&, bool);
template void mlp_backward(const MlpT<float>&, const MlpCacheT<float>&,
                           const Eigen::Ref<const MlpT<float>::Mat>&, MlpGradsT<float>&,
                           MlpT<float>::Mat*, const float*, bool);
template void mlp_backward(const MlpT<double>&, const MlpCacheT<double>&,
                           const Eigen::Ref<const MlpT<double>::Mat>&, MlpGradsT<double>&,
                           MlpT<double>::Mat*, const double*, bool);
template void mlp_forward_pair(const MlpT<float>&, const MlpT<float>&,
                               const Eigen::Ref<const MlpT<float>::Mat>&, MlpCacheT<float>&,
                               MlpT<float>::Mat&, MlpCacheT<float>&, MlpT<float>::Mat&);
template void mlp_forward_pair(const MlpT<double>&, const MlpT<double>&,
                               const Eigen::Ref<const MlpT<double>::Mat>&, MlpCacheT<double>&,
                               MlpT<double>::Mat&, MlpCacheT<double>&, MlpT<double>::Mat&);
template void mlp_backward_pair(const MlpT<float>&, const MlpCacheT<float>&,
                                const Eigen::Ref<const MlpT<float>::Mat>&, MlpGradsT<float>&,
                                const MlpT<float>&, const MlpCacheT<float>&,
                                const Eigen::Ref<const MlpT<float>::Mat>&, MlpGradsT<float>&,
                                MlpT<float>::Mat&, const float*);
template void mlp_backward_pair(const MlpT<double>&, const MlpCacheT<double>&,
                                const Eigen::Ref<const MlpT<double>::Mat>&, MlpGradsT<double>&,
                                const MlpT<double>&, const MlpCacheT<double>&,
                                const Eigen::Ref<const MlpT<double>::Mat>&, MlpGradsT<double>&,
                                MlpT<double>::Mat&, const double*);

}  // namespace ks
