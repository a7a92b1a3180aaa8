#pragma once
// Density control as mesh operations on the canonical template (one Gaussian per vertex).
// Every operation is pure: it returns the new faces and a sparse stencil S (N_new x N_old, each row
// a convex combination of old vertices) that the caller applies to ALL per-vertex arrays
// (TrainerState::apply_stencil: anchors, skin weights, biases, statistics, Adam moments).
// Modes (docs/avatar.md):
//   gpdc   SinGS's geometry-preserving density control: split high-gradient faces at edge
//          midpoints (conforming red-green refinement), rescale oversized and new Gaussians to the
//          mean size, collapse edges of near-transparent Gaussians (shortest edge first, link
//          condition, no boundary, no normal flips).
//   vertex SIAvatar's vertex-based densification: the faces around vertices whose view-space
//          gradient exceeds tau are split 1->4 (conforming closure).
//   naive  3DGS clone/split/prune ignoring the mesh (ablation).
//   off    nothing.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "reconstruct/density.hpp"

namespace ks {

using Stencil = Eigen::SparseMatrix<double, Eigen::RowMajor>;

struct MeshEdit {
  Eigen::MatrixXi faces;        // new faces, indexing the new vertex set
  Stencil S;                    // N_new x N_old
  std::vector<int> old_to_new;  // N_old: row now holding each old vertex (-1: removed)
  std::vector<int> new_rows;    // rows that are new vertices (not a kept old vertex)
  int num_vertices() const { return int(S.rows()); }
};

// Splits the selected faces 1->4 at edge midpoints and keeps the mesh conforming: a face with two
// split edges is promoted to a full 1->4 split (repeated until stable); a face with one split
// edge is bisected 1->2. Orientation kept. Old vertices keep their indices; midpoints are
// appended (rows N_old..), each a 0.5/0.5 stencil row.
MeshEdit split_faces(const Eigen::MatrixXi& F, int num_vertices,
                     const std::vector<uint8_t>& face_selected);

// Faces incident to any selected vertex.
std::vector<uint8_t> faces_around_vertices(const Eigen::MatrixXi& F,
                                           const std::vector<uint8_t>& vertex_selected);

struct CollapseOptions {
  double min_normal_dot = 0.2;  // reject a collapse that turns a face normal by more than ~78deg
  int max_collapses = -1;       // -1: no limit
};
// Removes the candidate vertices by edge collapse. For each candidate, the incident edges are
// ranked by length (shortest first, globally across candidates); an edge (u, v) with v a candidate
// collapses v into u: onto u's position (stencil row 1.0 at u) when u is not a candidate, to the
// midpoint (0.5/0.5) when both are. A collapse is allowed only if neither endpoint is on the
// boundary, the link condition holds (exactly two common neighbours, which are the edge's two
// opposite vertices, each of valence > 3, and no face (u,w,x)+(v,w,x) pair: no tetrahedron
// fold), and no surviving face flips (normal dot < min_normal_dot). Collapses in one call touch
// disjoint 1-rings so each check sees the current mesh. Vertices are compacted (kept order).
MeshEdit collapse_vertices(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F,
                           const std::vector<uint8_t>& candidates, const CollapseOptions& opt = {});

// Naive 3DGS densification (ignores the mesh): vertices with high gradient are cloned (small
// Gaussians) or split into two samples of the Gaussian (large ones); low-opacity or oversized
// ones are pruned (their faces dropped). New vertices copy the parent (stencil row 1.0), so they
// inherit anchor, skin weights and statistics; the caller then moves them to `positions` and
// adds `log_scale_delta` to their log-scale bias.
struct NaiveOptions {
  float grad_threshold = 0.0003f;  // on the gradient as given (density.cpp passes NDC units)
  float percent_dense = 0.01f;     // clone if max scale <= percent_dense * extent, else split
  float prune_opacity = 0.005f;    // prune below this opacity
  float prune_scale = 0.1f;        // prune max scale above this fraction of the extent
  float clone_jitter = 0.1f;       // clone offset, in units of the Gaussian's scale
  uint64_t seed = 0;
};
struct NaiveEdit {
  MeshEdit edit;
  std::vector<int> moved_rows;             // rows whose anchor must be set to `positions`
  std::vector<Eigen::Vector3d> positions;  // one per moved row
  std::vector<float> log_scale_delta;      // N_new: add to the log-scale bias
  int cloned = 0, split = 0, pruned = 0;
};
// mean_grad: N (mean view-space gradient per vertex); g: the decoded canonical Gaussians (N).
NaiveEdit naive_densify(const Eigen::MatrixXd& anchors, const Eigen::MatrixXi& F,
                        const std::vector<float>& mean_grad, const Gaussians& g,
                        const NaiveOptions& opt);

// Composition: the stencil that applies A then B (B.S * A.S), with B's faces.
MeshEdit compose(const MeshEdit& a, const MeshEdit& b);

// ---- The trainer-facing density control (implements ks::DensityControl). ----
struct DensityOptions {
  // Schedule: act every `interval` iterations within [start, stop); 0 = automatic from the
  // trainer's total: start 25%, stop 75%, interval total/10 (at least 1).
  int start = 0, stop = 0, interval = 0;
  // tau on the mean view-space gradient in 3DGS's NDC units (SIAvatar: 0.0003). The trainer
  // accumulates |dL/dmean2d| in pixels; NDC units = pixels * (training image width / 2).
  float grad_threshold = 0.0003f;
  int image_width = 0;  // training image width in pixels; 0: assume 256 (512 px images at 0.5)
  int max_vertices = 400000;        // no densification beyond this many vertices
  float max_split_fraction = 0.1f;  // at most this fraction of faces selected per step
  // gpdc
  float transparent_opacity = 0.05f;    // collapse vertices whose opacity is below this
  float oversize_factor = 2.5f;         // rescale Gaussians larger than this times the mean size
  float max_collapse_fraction = 0.05f;  // at most this fraction of vertices collapsed per step
  // naive
  NaiveOptions naive;
  bool verbose = false;  // print one line per action to stderr
};

// name: "gpdc", "vertex", "naive" or "off". Throws ks::Error for another name.
std::unique_ptr<DensityControl> make_density_control(const std::string& name,
                                                     const DensityOptions& options = {});
const std::vector<std::string>& density_control_names();
// Throws ks::Error ("density control "X": expected gpdc, vertex, naive or off") unless `name` is
// one of density_control_names().
void require_density_name(const std::string& name);

// Statistics of the last actions of a control (for logs and tests).
struct DensityStats {
  int steps = 0, added = 0, removed = 0, rescaled = 0;
};
const DensityStats* density_stats(const DensityControl& control);

}  // namespace ks
