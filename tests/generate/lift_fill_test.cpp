// The lift's step 4 (generate/lift_fill.hpp): fill by propagation, smoothing where not seen.
#include <gtest/gtest.h>

#include <cmath>

#include "generate/lift_fill.hpp"
#include "generate/lift_mirrors.hpp"
#include "generate/lift_seen.hpp"
#include "lift_case.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

namespace {

// An n x n grid of vertices (row-major), two triangles per cell; `copies` disconnected grids.
Eigen::MatrixXi grid_faces(int n, int copies = 1) {
  Eigen::MatrixXi F(2 * (n - 1) * (n - 1) * copies, 3);
  int f = 0;
  for (int c = 0; c < copies; ++c)
    for (int y = 0; y + 1 < n; ++y)
      for (int x = 0; x + 1 < n; ++x) {
        const int a = c * n * n + y * n + x, b = a + 1, d = a + n, e = d + 1;
        F.row(f++) << a, b, e;
        F.row(f++) << a, e, d;
      }
  return F;
}

}  // namespace

TEST(LiftFill, PropagationLeavesNoVertexUncoloured) {
  const int n = 9;
  const auto adj = vertex_adjacency(grid_faces(n), n * n);
  Eigen::MatrixXd colour = Eigen::MatrixXd::Constant(n * n, 3, std::nan(""));
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(n * n);
  const Eigen::RowVector3d c(0.2, 0.5, 0.7);
  for (int y = 0; y < n; ++y) {  // the first column known
    colour.row(y * n) = c;
    weight(y * n) = 1.0;
  }
  weight(n * n - 1) = 0.04;  // below known_weight: unknown
  const int filled = lift::fill_by_propagation(adj, weight, 0.05, colour);
  EXPECT_EQ(filled, n * n - n);
  for (int i = 0; i < n * n; ++i)
    for (int k = 0; k < 3; ++k) {
      ASSERT_FALSE(std::isnan(colour(i, k))) << "vertex " << i;
      EXPECT_NEAR(colour(i, k), c(k), 1e-12);
    }
}

TEST(LiftFill, PropagationTakesTheMeanOfKnownNeighbours) {
  const int n = 3;  // a row of three known 0, unknown, known 1 in the middle row
  const auto adj = vertex_adjacency(grid_faces(n), n * n);
  Eigen::MatrixXd colour = Eigen::MatrixXd::Zero(n * n, 3);
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(n * n);
  colour.row(3).setConstant(0.0);
  colour.row(5).setConstant(1.0);
  weight(3) = weight(5) = 1.0;
  lift::fill_by_propagation(adj, weight, 0.05, colour);
  // Vertex 4 neighbours 3 and 5 (and others unknown in the first ring): their mean.
  EXPECT_NEAR(colour(4, 0), 0.5, 1e-12);
  for (int i = 0; i < n * n; ++i) {
    EXPECT_GE(colour(i, 0), 0.0);
    EXPECT_LE(colour(i, 0), 1.0);
  }
}

TEST(LiftFill, PropagationStopsWhereNoKnownVertexReaches) {
  const int n = 5;
  const auto adj = vertex_adjacency(grid_faces(n, 2), 2 * n * n);
  Eigen::MatrixXd colour = Eigen::MatrixXd::Constant(2 * n * n, 3, -1.0);
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(2 * n * n);
  colour.row(0).setConstant(0.3);
  weight(0) = 1.0;
  EXPECT_EQ(lift::fill_by_propagation(adj, weight, 0.05, colour), n * n - 1);
  for (int i = 0; i < n * n; ++i) EXPECT_NEAR(colour(i, 0), 0.3, 1e-12);
  for (int i = n * n; i < 2 * n * n; ++i) EXPECT_EQ(colour(i, 0), -1.0);  // the other grid
}

TEST(LiftFill, SmoothingMovesOnlyWhatIsNotKept) {
  const int n = 7;
  const auto adj = vertex_adjacency(grid_faces(n), n * n);
  Eigen::MatrixXd colour = Eigen::MatrixXd::Zero(n * n, 3);
  Eigen::VectorXd keep = Eigen::VectorXd::Zero(n * n);
  for (int i = 0; i < n * n; ++i) {
    colour.row(i).setConstant(i % 2 ? 1.0 : 0.0);  // a checker of 0 and 1 (by index)
    if (i < n) keep(i) = 1.5;                      // the first row kept (keep clamped to 1)
  }
  const Eigen::MatrixXd before = colour;
  lift::smooth_unseen(adj, keep, 3, colour);
  for (int i = 0; i < n; ++i) EXPECT_EQ(colour(i, 0), before(i, 0));
  // Elsewhere the smoothing pulls towards the neighbours' mean: the spread shrinks.
  double spread_before = 0, spread_after = 0;
  for (int i = n; i < n * n; ++i) {
    spread_before += std::abs(before(i, 0) - 0.5);
    spread_after += std::abs(colour(i, 0) - 0.5);
    EXPECT_GE(colour(i, 0), 0.0);
    EXPECT_LE(colour(i, 0), 1.0);
  }
  EXPECT_LT(spread_after, 0.5 * spread_before);
  // A constant colour is a fixed point; no passes change nothing.
  Eigen::MatrixXd flat = Eigen::MatrixXd::Constant(n * n, 3, 0.25);
  lift::smooth_unseen(adj, Eigen::VectorXd::Zero(n * n), 4, flat);
  EXPECT_NEAR((flat.array() - 0.25).abs().maxCoeff(), 0.0, 1e-15);
  Eigen::MatrixXd same = before;
  lift::smooth_unseen(adj, Eigen::VectorXd::Zero(n * n), 0, same);
  EXPECT_EQ(same, before);
}

TEST(LiftFill, NoVertexOfALiftedBodyIsLeftUncoloured) {
  // Steps 2 and 3 on the bare body, every vertex they leave unknown marked; the fill colours
  // them all (the body is one connected surface).
  const test::LiftCase c(1);
  const LiftOptions& o = c.options;
  const lift::LiftBody& b = c.body;
  const lift::SeenColour seen =
      lift::seen_colour(c.photo, lift::inner_mask(c.mask, o), b.posed.vertices, b.posed_normals,
                        b.render, c.fit.camera, o);
  const lift::Mirrors mirrors =
      lift::find_mirrors(b.person.rest, b.person.faces, b.rest_normals, b.person.skin_joints, b, o);
  lift::Blend blend = lift::blend_colours(seen, mirrors, lift::head_colours(seen, b, o), b, o);
  int unknown = 0;
  for (long i = 0; i < blend.colour.rows(); ++i)
    if (blend.weight(i) < o.known_weight) {
      blend.colour.row(i).setConstant(std::nan(""));
      ++unknown;
    }
  ASSERT_GT(unknown, 0);
  const auto adj = vertex_adjacency(b.person.faces, int(b.vertices()));
  EXPECT_EQ(lift::fill_by_propagation(adj, blend.weight, o.known_weight, blend.colour), unknown);
  EXPECT_FALSE(blend.colour.array().isNaN().any());
  EXPECT_GE(blend.colour.minCoeff(), 0.0);
  EXPECT_LE(blend.colour.maxCoeff(), 1.0);
}

}  // namespace ks
