#pragma once
// The decoder MLPs' first layer evaluated in texel space. A point's feature is the bilinear blend
// of four texels in each of the three planes (triplane.hpp), and the first layer before its ReLU
// is linear in the feature, so the two commute:
//   W0 f + b0 = b0 + sum over planes p and the lookup's texels t of  w_t (W0_p t)
// where W0_p is W0's block of columns for plane p. With Q = W0_p t computed once for every texel
// the points read (about 160,000 at the defaults against 165,000 points, each read by 12 points
// on average), the first layer costs C x H multiply-adds a texel instead of 3C x H a point, and
// the point's part is a blend of 12 rows of Q. The backward is the same in reverse: a texel's dQ
// is the sum of the gradients of the layer's output (d0, after the ReLU's mask) of the points
// that read it, times their weights (gathered texel by texel), then dW0_p += dQ t^T and
// dt = W0_p^T dQ.
// The same model and, up to float rounding, the same numbers as the point-wise first layer
// (mlp.hpp) on triplane_forward's features. Float only, with the AVX2+FMA kernels (the MLPs' and
// the triplane's): available() says when; KS_DECODER_NO_TEXEL_LAYER0=1 turns it off.
#include <cstdint>
#include <vector>

#include "reconstruct/mlp.hpp"
#include "reconstruct/triplane.hpp"
#include "reconstruct/triplane_kernels.hpp"

namespace ks {

class TexelLayer0 {
 public:
  // Whether it can serve this triplane and these MLPs (which all read its features): the CPU has
  // AVX2 and FMA (and neither the MLPs nor the triplane are forced to their portable paths), the
  // channels and every MLP's first-layer width are multiples of 8, each MLP has two layers or
  // more, and neither KS_DECODER_NO_TEXEL_LAYER0 nor set_path turn it off.
  static bool available(const Triplane& tp, const Mlp* const* mlps, int count);
  enum class Path { kAuto, kPoints };
  // For tests and benchmarks: kPoints turns it off (not thread-safe against concurrent decodes).
  static void set_path(Path p);

  // The points (xs, ys, zs) [0, n) of the forwards and backwards to come, and the texels marked
  // as triplane_mark_texels marks them (those the points read; a superset is fine): the rows of
  // Q. Call again whenever either changes.
  void set_points(const Triplane& tp, const std::vector<uint8_t>& marked, const float* xs,
                  const float* ys, const float* zs, int n);

  // The MLPs' first layers after their ReLU for the points, written to each cache's act[1]
  // (sized by mlp_tail_buffers).
  void forward(const Triplane& tp, const Mlp* const* mlps, int count, MlpCache* const* caches);
  // From d0 (the first layers' pre-activation gradients, all MLPs' rows stacked in `mlps` order:
  // H x n, H = the sum of their widths) to the gradients: each MLP's first-layer weights (added to
  // g[q]->W[0]) and the planes' (written, not added, to dplanes for every texel of the set; the
  // others are left as they are).
  void backward(const Triplane& tp, const Mlp* const* mlps, int count, const float* d0,
                MlpGrads* const* g, float* dplanes);

  // H: the sum of the MLPs' first-layer widths.
  static int width(const Mlp* const* mlps, int count);

 private:
  // A run of neighbouring texels of one plane: texel index (all planes) and its first row of Q.
  struct Run {
    int plane;
    int texel;
    int row;
    int len;
  };
  // W0_p packed for the kernels (H x C, and C x H transposed), per plane; the stacked biases.
  void pack(const Triplane& tp, const Mlp* const* mlps, int count);
  // Calls f(run, first row, end row) for the parts of runs in rows [r0, r1), in order.
  template <class F>
  void for_runs(int r0, int r1, F&& f) const;
  // Row r of run `run`'s texel in planes (or their gradient): C floats.
  template <class T>
  static T* texel(T* planes, const Run& run, int r, int C) {
    return planes + (size_t(run.texel) + size_t(r - run.row)) * size_t(C);
  }
  std::vector<int> cidx_;                     // per texel: its row of Q, -1 when not in the set
  std::vector<triplane_kernels::Taps> taps_;  // plane p, point i at p n + i
  int n_ = 0;
  std::vector<Run> runs_;            // in texel order
  std::vector<int> chunk_run_;       // per chunk of rows: the run holding its first row
  int rows_ = 0;                     // rows of Q
  int plane_row_[4] = {0, 0, 0, 0};  // plane p's rows: [plane_row_[p], plane_row_[p + 1])
  std::vector<float> a_, at_, bias_;
  std::vector<float> q_;  // rows_ x H
  // The taps by row of Q: row r's points and weights at [row_start_[r], row_start_[r + 1]).
  std::vector<int> row_start_, row_point_;
  std::vector<float> row_weight_;
  std::vector<float> partials_;  // per chunk: H x C weight-gradient partials
  int H_ = 0;
};

}  // namespace ks
