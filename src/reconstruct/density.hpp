#pragma once
// Density control interface for the avatar fit (implemented by src/reconstruct/density*.cpp:
// SinGS's geometry-preserving density control, SIAvatar's vertex-based densification, naive 3DGS).
//
// The avatar is one Gaussian per vertex of a canonical template mesh (anchor). Attributes come
// from a triplane + MLP decoders evaluated at the anchor, so adding a vertex needs no per-Gaussian
// parameters: it gets its attributes from the networks at its position. Density control therefore
// edits the *mesh*: it builds a sparse stencil S (N_new x N_old) mapping every per-vertex
// attribute (anchor position, skin weights, statistics, per-vertex scale bias) to the new vertex
// set, plus the new faces, and calls TrainerState::apply_stencil. Midpoint insertion, edge collapse
// and removal are all stencils (a removed vertex has no row; a collapsed pair becomes one row with
// two 0.5 entries; a kept vertex is a row with one 1.0 entry).
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "gaussians/gaussians.hpp"

namespace ks {

struct TrainerState {
  int iteration = 0;  // the iteration that just finished (0-based)
  int total_iterations = 0;

  // Canonical template (rest pose) on which Gaussians are anchored: one Gaussian per vertex.
  Eigen::MatrixXd anchors;       // N x 3 (rows = vertices)
  Eigen::MatrixXi faces;         // M x 3
  std::vector<int> part_labels;  // N, SinGS's 15 parts (body/parts.hpp)
  // Top-4 skin weights per vertex: joint indices and weights (renormalised to sum 1).
  std::vector<int> skin_joints;     // 4N
  std::vector<float> skin_weights;  // 4N

  // The canonical Gaussians as decoded at the last iteration (read-only for density control:
  // opacity and scale decide pruning / rescaling). means = anchor + offset.
  Gaussians canonical;

  // Per-vertex additive log-scale bias (all three axes), applied after decoding. Density control
  // writes it to rescale oversized / new Gaussians (e.g. to the mean size). Starts at 0.
  std::vector<float> log_scale_bias;  // N

  // View-space gradient statistics accumulated since the last reset: for each vertex the sum of
  // ||dL/dmean2d|| (pixels) over the iterations in which it was visible, and that count; plus the
  // largest screen radius seen. Density control resets them (reset_stats) after acting.
  std::vector<float> grad2d_accum;  // N
  std::vector<int> grad2d_count;    // N
  std::vector<int> max_radius;      // N

  int num_vertices() const { return int(anchors.rows()); }

  // Replaces the vertex set: every per-vertex array is mapped through S (N_new x N_old, each row
  // a convex combination of old vertices): anchors, skin weights (re-reduced to the top 4 and
  // renormalised, body/skin_weights.hpp remap_top_k), log_scale_bias, statistics; part labels take
  // the largest-weight source. `new_faces` index the new vertex set. The trainer's own per-vertex
  // buffers follow (it keeps them in step through `on_resize`). Throws ks::Error if S or the faces
  // are inconsistent.
  void apply_stencil(const Eigen::SparseMatrix<double, Eigen::RowMajor>& S,
                     const Eigen::MatrixXi& new_faces);
  void reset_stats();

  // Set by the trainer: called at the end of apply_stencil with the stencil just applied.
  void (*on_resize)(void* ctx, const Eigen::SparseMatrix<double, Eigen::RowMajor>& S) = nullptr;
  void* on_resize_ctx = nullptr;
};

class DensityControl {
 public:
  virtual ~DensityControl() = default;
  // Called by the trainer after every optimisation step (after the statistics of this iteration
  // were accumulated). The implementation decides itself when to act (interval, start, stop).
  virtual void step(int iteration, TrainerState& state) = 0;
  // Whether step() may act after this iteration (and so read TrainerState::canonical, which the
  // trainer then fills; copying every iteration's decode would cost a step about as much as SSIM).
  virtual bool acts_at(int /*iteration*/, int /*total_iterations*/) const { return true; }
};

}  // namespace ks
