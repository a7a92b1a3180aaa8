#include "reconstruct/density_ops.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <map>
#include <random>
#include <set>

#include "core/error.hpp"

namespace ks {
namespace {

struct Mesh {
  Eigen::MatrixXd V;
  Eigen::MatrixXi F;
};

Mesh octahedron() {
  Mesh m;
  m.V.resize(6, 3);
  m.V << 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1;
  m.F.resize(8, 3);
  // Counter-clockwise seen from outside.
  m.F << 0, 2, 4, 4, 2, 1, 1, 2, 5, 5, 2, 0, 0, 4, 3, 4, 1, 3, 1, 5, 3, 5, 0, 3;
  return m;
}

// Octahedron refined `levels` times by full midpoint splits, projected to the unit sphere.
Mesh sphere(int levels) {
  Mesh m = octahedron();
  for (int l = 0; l < levels; ++l) {
    const MeshEdit e = split_faces(m.F, int(m.V.rows()), std::vector<uint8_t>(m.F.rows(), 1));
    m.V = e.S * m.V;
    m.F = e.faces;
  }
  m.V.rowwise().normalize();
  return m;
}

// Closed, consistently oriented 2-manifold: every directed edge once, its reverse once, and each
// vertex's faces form one fan (a single cycle).
bool closed_manifold(const Eigen::MatrixXi& F, int N) {
  std::map<std::pair<int, int>, int> directed;
  std::vector<int> used(N, 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      if (a == b) return false;
      if (++directed[{a, b}] > 1) return false;
      used[a] = 1;
    }
  for (const auto& [e, c] : directed)
    if (!directed.count({e.second, e.first})) return false;
  // One cycle around each vertex: follow next-edge pointers.
  std::vector<std::map<int, int>> next(N);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) next[F(f, k)][F(f, (k + 1) % 3)] = F(f, (k + 2) % 3);
  for (int v = 0; v < N; ++v) {
    if (!used[v]) return false;  // isolated vertex
    const int start = next[v].begin()->first;
    int cur = start;
    size_t steps = 0;
    do {
      auto it = next[v].find(cur);
      if (it == next[v].end()) return false;
      cur = it->second;
      ++steps;
    } while (cur != start && steps <= next[v].size());
    if (steps != next[v].size()) return false;
  }
  return true;
}

int euler(const Eigen::MatrixXi& F, int N) {
  std::set<std::pair<int, int>> edges;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      int a = F(f, k), b = F(f, (k + 1) % 3);
      edges.insert({std::min(a, b), std::max(a, b)});
    }
  return N - int(edges.size()) + int(F.rows());
}

void expect_rows_sum_to_one(const Stencil& S) {
  for (int r = 0; r < S.rows(); ++r) {
    double s = 0;
    int n = 0;
    for (Stencil::InnerIterator it(S, r); it; ++it) {
      EXPECT_GT(it.value(), 0.0);
      s += it.value();
      ++n;
    }
    EXPECT_GT(n, 0) << "row " << r;
    EXPECT_NEAR(s, 1.0, 1e-12) << "row " << r;
  }
}

TEST(DensityOps, SplitAllIsMidpointSubdivision) {
  const Mesh m = octahedron();
  const MeshEdit e = split_faces(m.F, 6, std::vector<uint8_t>(8, 1));
  EXPECT_EQ(e.num_vertices(), 6 + 12);
  EXPECT_EQ(e.faces.rows(), 32);
  EXPECT_EQ(e.new_rows.size(), 12u);
  EXPECT_TRUE(closed_manifold(e.faces, e.num_vertices()));
  EXPECT_EQ(euler(e.faces, e.num_vertices()), 2);
  expect_rows_sum_to_one(e.S);
  // Midpoints are at edge midpoints.
  const Eigen::MatrixXd V = e.S * m.V;
  for (int r : e.new_rows) EXPECT_NEAR(V.row(r).norm(), std::sqrt(0.5), 1e-12);
}

TEST(DensityOps, PartialSplitStaysConforming) {
  const Mesh m = sphere(2);
  const int N = int(m.V.rows());
  std::mt19937 rng(3);
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<uint8_t> sel(m.F.rows(), 0);
    for (auto& s : sel) s = (rng() % 7) == 0;
    const MeshEdit e = split_faces(m.F, N, sel);
    EXPECT_TRUE(closed_manifold(e.faces, e.num_vertices())) << "trial " << trial;
    EXPECT_EQ(euler(e.faces, e.num_vertices()), 2);
    expect_rows_sum_to_one(e.S);
    EXPECT_EQ(e.num_vertices(), N + int(e.new_rows.size()));
    // Every selected face became four: at least 3 more faces per selected face.
    const int nsel = int(std::count(sel.begin(), sel.end(), 1));
    EXPECT_GE(e.faces.rows(), m.F.rows() + 3 * nsel);
    // Old vertices keep their index (identity rows).
    for (int v = 0; v < N; ++v) EXPECT_DOUBLE_EQ(e.S.coeff(v, v), 1.0);
    // Orientation kept: all normals still point outwards on the sphere.
    const Eigen::MatrixXd V = e.S * m.V;
    for (Eigen::Index f = 0; f < e.faces.rows(); ++f) {
      const Eigen::Vector3d a = V.row(e.faces(f, 0)), b = V.row(e.faces(f, 1)),
                            c = V.row(e.faces(f, 2));
      EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0);
    }
  }
}

TEST(DensityOps, SingleFaceSplitClosesWithBisections) {
  const Mesh m = octahedron();
  std::vector<uint8_t> sel(8, 0);
  sel[0] = 1;
  const MeshEdit e = split_faces(m.F, 6, sel);
  EXPECT_EQ(e.num_vertices(), 9);        // three midpoints
  EXPECT_EQ(e.faces.rows(), 8 + 3 + 3);  // 1->4 plus three neighbours 1->2
  EXPECT_TRUE(closed_manifold(e.faces, 9));
}

TEST(DensityOps, FacesAroundVertices) {
  const Mesh m = octahedron();
  std::vector<uint8_t> v(6, 0);
  v[2] = 1;  // the top vertex: 4 faces
  const auto f = faces_around_vertices(m.F, v);
  EXPECT_EQ(std::count(f.begin(), f.end(), 1), 4);
  const MeshEdit e = split_faces(m.F, 6, f);
  EXPECT_TRUE(closed_manifold(e.faces, e.num_vertices()));
  EXPECT_EQ(euler(e.faces, e.num_vertices()), 2);
}

TEST(DensityOps, CollapseKeepsManifoldAndRemovesCandidates) {
  const Mesh m = sphere(2);
  const int N = int(m.V.rows());
  std::vector<uint8_t> cand(N, 0);
  const std::vector<int> picks = {7, 20, 33, 50, 61};
  for (int p : picks) cand[p] = 1;
  const MeshEdit e = collapse_vertices(m.V, m.F, cand);
  const int removed = N - e.num_vertices();
  EXPECT_GT(removed, 0);
  EXPECT_LE(removed, int(picks.size()));
  EXPECT_TRUE(closed_manifold(e.faces, e.num_vertices()));
  EXPECT_EQ(euler(e.faces, e.num_vertices()), 2);
  EXPECT_EQ(e.faces.rows(), m.F.rows() - 2 * removed);
  expect_rows_sum_to_one(e.S);
  // Only candidates were removed; kept non-candidates stay where they were (half-edge collapse).
  for (int v = 0; v < N; ++v)
    if (e.old_to_new[v] < 0) {
      EXPECT_TRUE(cand[v]) << v;
    }
  const Eigen::MatrixXd V2 = e.S * m.V;
  for (int v = 0; v < N; ++v)
    if (!cand[v] && e.old_to_new[v] >= 0) {
      EXPECT_LT((V2.row(e.old_to_new[v]) - m.V.row(v)).norm(), 1e-12);
    }
}

TEST(DensityOps, CollapseAllCandidatesRespectsLinkCondition) {
  const Mesh m = sphere(1);
  const int N = int(m.V.rows());
  std::vector<uint8_t> cand(N, 1);  // everything transparent: collapse as much as is legal
  Mesh cur = m;
  for (int round = 0; round < 10; ++round) {
    std::vector<uint8_t> c(cur.V.rows(), 1);
    const MeshEdit e = collapse_vertices(cur.V, cur.F, c);
    ASSERT_TRUE(closed_manifold(e.faces, e.num_vertices())) << "round " << round;
    ASSERT_EQ(euler(e.faces, e.num_vertices()), 2);
    if (e.num_vertices() == cur.V.rows()) break;
    cur.V = e.S * cur.V;
    cur.F = e.faces;
  }
  EXPECT_LT(cur.V.rows(), N);
  EXPECT_GE(cur.V.rows(), 4);
}

TEST(DensityOps, CollapseRefusesTetrahedronAndBoundary) {
  Eigen::MatrixXd V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  Eigen::MatrixXi F(4, 3);
  F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  const MeshEdit e = collapse_vertices(V, F, std::vector<uint8_t>(4, 1));
  EXPECT_EQ(e.num_vertices(), 4);
  // Open mesh: the octahedron without one face; its boundary vertices are never collapsed.
  const Mesh m = sphere(1);
  Eigen::MatrixXi Fo = m.F.bottomRows(m.F.rows() - 1);
  std::vector<uint8_t> cand(m.V.rows(), 0);
  for (int k = 0; k < 3; ++k) cand[m.F(0, k)] = 1;
  const MeshEdit eo = collapse_vertices(m.V, Fo, cand);
  EXPECT_EQ(eo.num_vertices(), m.V.rows());
}

TEST(DensityOps, NaiveCloneSplitPruneCounts) {
  const Mesh m = sphere(1);  // 18 vertices, extent 1
  const int N = int(m.V.rows());
  Gaussians g;
  g.resize(N);
  std::vector<float> grad(N, 0.f);
  for (int i = 0; i < N; ++i) {
    g.opacity_logits[i] = 3.f;
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(0.005f);  // small
  }
  // 0,1: clone (small, high gradient); 2,3,4: split (large, high gradient);
  // 5: prune (transparent); 6: prune (huge); 7: high gradient but transparent -> pruned.
  grad[0] = grad[1] = 1.f;
  for (int i : {2, 3, 4}) {
    grad[i] = 1.f;
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(0.05f);
  }
  g.opacity_logits[5] = -8.f;
  for (int k = 0; k < 3; ++k) g.log_scales[3 * 6 + k] = std::log(0.5f);
  g.opacity_logits[7] = -8.f;
  grad[7] = 1.f;
  NaiveOptions o;
  o.grad_threshold = 0.5f;
  const NaiveEdit ne = naive_densify(m.V, m.F, grad, g, o);
  EXPECT_EQ(ne.cloned, 2);
  EXPECT_EQ(ne.split, 3);
  EXPECT_EQ(ne.pruned, 3);
  EXPECT_EQ(ne.edit.num_vertices(), N - 3 + 2 + 3);
  EXPECT_EQ(ne.moved_rows.size(), 2u + 2u * 3u);
  expect_rows_sum_to_one(ne.edit.S);
  // Split halves get the 3DGS 1/1.6 scale.
  int shrunk = 0;
  for (float d : ne.log_scale_delta) shrunk += std::abs(d + std::log(1.6f)) < 1e-6f;
  EXPECT_EQ(shrunk, 6);
  // Faces touching pruned vertices are gone; the rest index the new set.
  EXPECT_LT(ne.edit.faces.rows(), m.F.rows());
  EXPECT_LT(ne.edit.faces.maxCoeff(), ne.edit.num_vertices());
  // Split samples lie near the parent (within a few sigma).
  for (size_t k = 0; k < ne.moved_rows.size(); ++k) {
    Eigen::MatrixXd V2 = ne.edit.S * m.V;
    EXPECT_LT((ne.positions[k] - Eigen::Vector3d(V2.row(ne.moved_rows[k]))).norm(), 0.3);
  }
}

TEST(DensityOps, ComposeChainsStencils) {
  const Mesh m = sphere(1);
  const MeshEdit a = split_faces(m.F, int(m.V.rows()), std::vector<uint8_t>(m.F.rows(), 1));
  std::vector<uint8_t> cand(a.num_vertices(), 0);
  cand[a.new_rows[0]] = 1;
  const Eigen::MatrixXd Va = a.S * m.V;
  const MeshEdit b = collapse_vertices(Va, a.faces, cand);
  const MeshEdit c = compose(a, b);
  EXPECT_LT(((c.S * m.V) - (b.S * Va)).norm(), 1e-12);
  EXPECT_TRUE(closed_manifold(c.faces, c.num_vertices()));
}

}  // namespace
}  // namespace ks
