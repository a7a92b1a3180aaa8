#include "reconstruct/texel_layer0.hpp"

#include <algorithm>
#include <cstdlib>

#include "core/env.hpp"
#include "core/error.hpp"
#include "reconstruct/mlp_kernels.hpp"
#include "reconstruct/triplane_kernels.hpp"

namespace ks {

namespace {
namespace mk = mlp_kernels;
namespace tk = triplane_kernels;

TexelLayer0::Path g_path = TexelLayer0::Path::kAuto;

// Rows of Q a task: the unit of the projections, the weight-gradient partials (summed in chunk
// order, so the results do not depend on the thread count) and the gathers.
constexpr int kChunk = 2048;
// Rows a kernel call in the backward: its dQ (96 x 64 floats, 24 KB) stays in L1 from the gather
// through the two kernels that read it (with 2048-row calls on a dQ in memory, 512 KB a call, as
// large as L2, those two kernels took 15 ms a step; with 96, 10.5).
constexpr int kSub = 96;
// Points a task in the blend.
constexpr int kPoints = 2048;
}  // namespace

void TexelLayer0::set_path(Path p) {
  g_path = p;
}

int TexelLayer0::width(const Mlp* const* mlps, int count) {
  int h = 0;
  for (int q = 0; q < count; ++q) h += int(mlps[q]->W.front().rows());
  return h;
}

bool TexelLayer0::available(const Triplane& tp, const Mlp* const* mlps, int count) {
  static const bool env_off = env_flag("KS_DECODER_NO_TEXEL_LAYER0");
  if (env_off || g_path == Path::kPoints || count < 1 || count > 2) return false;
  if (!mk::use_avx2() || !tk::use_avx2(tp.channels)) return false;
  for (int q = 0; q < count; ++q) {
    const Mlp& m = *mlps[q];
    if (m.W.size() < 2 || m.W[0].rows() % 8 != 0 || m.W[0].cols() != tp.feature_dim()) return false;
  }
  return true;
}

void TexelLayer0::set_points(const Triplane& tp, const std::vector<uint8_t>& marked,
                             const float* xs, const float* ys, const float* zs, int n) {
  const size_t per_plane = size_t(tp.res) * size_t(tp.res);
  if (marked.size() != 3 * per_plane)
    throw Error("TexelLayer0::set_points: the marks are not of this triplane");
  cidx_.assign(marked.size(), -1);
  runs_.clear();
  int row = 0;
  for (int p = 0; p < 3; ++p) {
    plane_row_[p] = row;
    const size_t end = (size_t(p) + 1) * per_plane;
    for (size_t t = size_t(p) * per_plane; t < end;) {
      if (!marked[t]) {
        ++t;
        continue;
      }
      size_t u = t;
      while (u < end && marked[u]) cidx_[u] = row + int(u - t), ++u;
      runs_.push_back({p, int(t), row, int(u - t)});
      row += int(u - t);
      t = u;
    }
  }
  plane_row_[3] = rows_ = row;
  const int chunks = (rows_ + kChunk - 1) / kChunk;
  chunk_run_.assign(size_t(chunks), 0);
  size_t r = 0;
  for (int c = 0; c < chunks; ++c) {
    while (runs_[r].row + runs_[r].len <= c * kChunk) ++r;
    chunk_run_[size_t(c)] = int(r);
  }
  taps_.resize(3 * size_t(n));
  n_ = n;
  bool unmarked = false;
#pragma omp parallel for schedule(static) if (n > 1024) reduction(|| : unmarked)
  for (int i = 0; i < n; ++i)
    for (int p = 0; p < 3; ++p) {
      const tk::Bilinear<float> b = tk::lookup(tp, p, xs[i], ys[i], zs[i]);
      const int* c = cidx_.data() + size_t(p) * per_plane + b.i00;
      tk::Taps& t = taps_[size_t(p) * size_t(n) + size_t(i)];
      t.row[0] = c[0], t.row[1] = c[b.du], t.row[2] = c[b.dv], t.row[3] = c[b.dv + b.du];
      t.w[0] = b.w00, t.w[1] = b.w10, t.w[2] = b.w01, t.w[3] = b.w11;
      for (int j = 0; j < 4; ++j) unmarked = unmarked || t.row[j] < 0;
    }
  if (unmarked) throw Error("TexelLayer0::set_points: a point reads a texel not marked");
  // The taps by row of Q, each row's points in increasing order (a counting sort).
  row_start_.assign(size_t(rows_) + 1, 0);
  for (const tk::Taps& t : taps_)
    for (int j = 0; j < 4; ++j) ++row_start_[size_t(t.row[j]) + 1];
  for (int r = 0; r < rows_; ++r) row_start_[size_t(r) + 1] += row_start_[size_t(r)];
  row_point_.resize(taps_.size() * 4);
  row_weight_.resize(row_point_.size());
  std::vector<int> fill(row_start_.begin(), row_start_.end() - 1);
  for (int i = 0; i < n; ++i)
    for (int p = 0; p < 3; ++p) {
      const tk::Taps& t = taps_[size_t(p) * size_t(n) + size_t(i)];
      for (int j = 0; j < 4; ++j) {
        const int e = fill[size_t(t.row[j])]++;
        row_point_[size_t(e)] = i;
        row_weight_[size_t(e)] = t.w[j];
      }
    }
}

template <class F>
void TexelLayer0::for_runs(int r0, int r1, F&& f) const {
  for (size_t r = size_t(chunk_run_[size_t(r0 / kChunk)]); r < runs_.size(); ++r) {
    const Run& run = runs_[r];
    if (run.row >= r1) break;
    const int a = std::max(r0, run.row), b = std::min(r1, run.row + run.len);
    if (a < b) f(run, a, b);
  }
}

void TexelLayer0::pack(const Triplane& tp, const Mlp* const* mlps, int count) {
  const int C = tp.channels;
  H_ = width(mlps, count);
  a_.assign(3 * size_t(H_) * size_t(C), 0.f);
  at_.assign(3 * size_t(C) * size_t(H_), 0.f);
  bias_.assign(size_t(H_), 0.f);
  int r0 = 0;
  for (int q = 0; q < count; ++q) {
    const Mlp::Mat& W = mlps[q]->W[0];
    for (int r = 0; r < int(W.rows()); ++r) {
      bias_[size_t(r0 + r)] = mlps[q]->b[0](r);
      for (int p = 0; p < 3; ++p)
        for (int j = 0; j < C; ++j) {
          const float w = W(r, p * C + j);
          // A_p: H x C, column j at j * H; A_p^T: C x H (C a multiple of 8), column r at r * C.
          a_[size_t(p) * H_ * C + size_t(j) * H_ + size_t(r0 + r)] = w;
          at_[size_t(p) * C * H_ + size_t(r0 + r) * C + size_t(j)] = w;
        }
    }
    r0 += int(W.rows());
  }
}

void TexelLayer0::forward(const Triplane& tp, const Mlp* const* mlps, int count,
                          MlpCache* const* caches) {
  const int n = n_;
  if (!available(tp, mlps, count)) throw Error("TexelLayer0::forward: not available here");
  if (cidx_.size() != tp.size() / size_t(tp.channels))
    throw Error("TexelLayer0::forward: set_points was not called for this triplane");
  for (int q = 0; q < count; ++q)
    if (caches[q]->act.size() < 2 || caches[q]->act[1].cols() != n ||
        caches[q]->act[1].rows() != mlps[q]->W[0].rows())
      throw Error("TexelLayer0::forward: a cache is not sized for these points");
  pack(tp, mlps, count);
  const int C = tp.channels, H = H_;
  q_.resize(size_t(rows_) * size_t(H));
  const int chunks = (rows_ + kChunk - 1) / kChunk;
  // Project the set's texels (they change every step) where they lie in the planes, run by run:
  // Q = W0_p t.
#pragma omp parallel for schedule(dynamic, 1)
  for (int c = 0; c < chunks; ++c)
    for_runs(c * kChunk, std::min(rows_, (c + 1) * kChunk), [&](const Run& run, int a, int b) {
      mk::gemm_cols(a_.data() + size_t(run.plane) * H * C, H, C, texel(tp.planes.data(), run, a, C),
                    C, b - a, q_.data() + size_t(a) * H, H, mk::Epilogue::kNone, nullptr, nullptr,
                    0);
    });
  // Each point: the bias plus its twelve texels' rows of Q, blended; the ReLU; out to the caches.
  const int h0 = int(mlps[0]->W[0].rows());
  float* out1 = count > 1 ? caches[1]->act[1].data() : nullptr;
  const int tasks = (n + kPoints - 1) / kPoints;
  const auto blend = mk::use_avx512() && H % 16 == 0 && h0 % 16 == 0 ? tk::blend_range_avx512
                                                                     : tk::blend_range_avx2;
#pragma omp parallel for schedule(dynamic, 1) if (tasks > 1)
  for (int t = 0; t < tasks; ++t)
    blend(taps_.data(), n, q_.data(), H, bias_.data(), t * kPoints, std::min(n, (t + 1) * kPoints),
          caches[0]->act[1].data(), h0, out1);
}

void TexelLayer0::backward(const Triplane& tp, const Mlp* const* mlps, int count, const float* d0,
                           MlpGrads* const* g, float* dplanes) {
  if (H_ != width(mlps, count) || q_.size() != size_t(rows_) * size_t(H_))
    throw Error("TexelLayer0::backward: not the MLPs of the last forward");
  const int C = tp.channels, H = H_;
  const int chunks = (rows_ + kChunk - 1) / kChunk;
  // Per sub-block of rows: dQ (each row the sum of its points' d0 times their weights, gathered
  // into L1), then, run by run, dW0_p += dQ t^T (a partial per chunk and plane, t read where it
  // lies in the planes) and dt = W0_p^T dQ, written where it goes in dplanes. dQ never goes to
  // memory.
  const size_t per = size_t(H) * size_t(C);
  partials_.resize(size_t(chunks) * 3 * per);
  const auto gather =
      mk::use_avx512() && H % 16 == 0 ? tk::gather_rows_avx512 : tk::gather_rows_avx2;
#pragma omp parallel for schedule(dynamic, 1)
  for (int c = 0; c < chunks; ++c) {
    static thread_local std::vector<float> dq;
    dq.resize(size_t(kSub) * size_t(H));
    std::fill_n(partials_.data() + size_t(c) * 3 * per, 3 * per, 0.f);
    const int r0 = c * kChunk, r1 = std::min(rows_, r0 + kChunk);
    for (int p = 0; p < 3; ++p) {
      const int a = std::max(r0, plane_row_[p]), b = std::min(r1, plane_row_[p + 1]);
      float* part = partials_.data() + (size_t(c) * 3 + size_t(p)) * per;
      for (int a2 = a; a2 < b; a2 += kSub) {
        const int b2 = std::min(b, a2 + kSub);
        gather(row_start_.data(), row_point_.data(), row_weight_.data(), a2, b2, d0, H, dq.data());
        for_runs(a2, b2, [&](const Run& run, int ra, int rb) {
          const float* dqa = dq.data() + size_t(ra - a2) * H;
          mk::outer_acc(dqa, H, H, texel(tp.planes.data(), run, ra, C), C, C, rb - ra, part,
                        nullptr);
          mk::gemm_cols(at_.data() + size_t(p) * C * H, C, H, dqa, H, rb - ra,
                        texel(dplanes, run, ra, C), C, mk::Epilogue::kNone, nullptr, nullptr, 0);
        });
      }
    }
  }
  // The partials in chunk order, to each MLP's first-layer weights (rows r0.. of the stack);
  // the weights' columns over the threads.
#pragma omp parallel for schedule(static)
  for (int col = 0; col < 3 * C; ++col) {
    const int p = col / C, j = col % C;
    int r0 = 0;
    for (int q = 0; q < count; ++q) {
      float* gw = g[q]->W[0].data() + size_t(col) * size_t(g[q]->W[0].rows());
      const int rows = int(g[q]->W[0].rows());
      for (int c = 0; c < chunks; ++c) {
        const float* src = partials_.data() + (size_t(c) * 3 + size_t(p)) * per + size_t(j) * H;
        for (int r = 0; r < rows; ++r) gw[r] += src[r0 + r];
      }
      r0 += rows;
    }
  }
}

}  // namespace ks
