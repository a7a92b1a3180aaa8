#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <set>

#include "body/body_model.hpp"
#include "mesh/trimesh.hpp"

namespace ks {
namespace {

const std::vector<std::string> kSmplNames = {
    "pelvis",     "left_hip",    "right_hip",    "spine1",      "left_knee",     "right_knee",
    "spine2",     "left_ankle",  "right_ankle",  "spine3",      "left_foot",     "right_foot",
    "neck",       "left_collar", "right_collar", "head",        "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist",   "right_wrist", "left_hand",     "right_hand"};
const std::vector<int> kSmplParents = {-1, 0, 0, 0,  1,  2,  3,  4,  5,  6,  7,  8,
                                       9,  9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};

// Mirror partner of each vertex (x -> -x), -1 where none lies within `tol`.
std::vector<int> mirror_map(const Eigen::MatrixXd& V, double tol) {
  std::map<std::tuple<long, long, long>, std::vector<int>> cells;
  auto key = [&](double x, double y, double z) {
    return std::make_tuple(std::lround(x / 0.01), std::lround(y / 0.01), std::lround(z / 0.01));
  };
  for (int v = 0; v < V.rows(); ++v) cells[key(V(v, 0), V(v, 1), V(v, 2))].push_back(v);
  std::vector<int> out(size_t(V.rows()), -1);
  for (int v = 0; v < V.rows(); ++v) {
    const Eigen::Vector3d m(-V(v, 0), V(v, 1), V(v, 2));
    const auto [cx, cy, cz] = key(m.x(), m.y(), m.z());
    double best = tol;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          auto it = cells.find({cx + dx, cy + dy, cz + dz});
          if (it == cells.end()) continue;
          for (int u : it->second) {
            const double d = (V.row(u).transpose() - m).norm();
            if (d <= best) {
              best = d;
              out[size_t(v)] = u;
            }
          }
        }
  }
  return out;
}

int mirror_part(int p) {
  switch (p) {
    case kHeadNeck:
    case kTorso:
    case kHips:
      return p;
    default:  // left/right parts alternate in SinGS's order
      return (p % 2 == 1) ? p + 1 : p - 1;
  }
}

TEST(DefaultBody, ClosedGenus0Manifold) {
  const BodyModel& m = default_body_model();
  EXPECT_EQ(m.kind, BodyKind::kDefault);
  EXPECT_GE(m.num_vertices(), 5000);
  EXPECT_LE(m.num_vertices(), 15000);
  EXPECT_TRUE(is_closed_manifold(m.faces, m.num_vertices()));
  EXPECT_EQ(euler_characteristic(m.faces, m.num_vertices()), 2);
  // One connected component, every vertex used.
  const auto adj = vertex_adjacency(m.faces, m.num_vertices());
  std::vector<char> seen(size_t(m.num_vertices()), 0);
  std::vector<int> stack = {0};
  seen[0] = 1;
  int count = 0;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    ++count;
    for (int u : adj[size_t(v)])
      if (!seen[size_t(u)]) seen[size_t(u)] = 1, stack.push_back(u);
  }
  EXPECT_EQ(count, m.num_vertices());
  // Outward orientation: positive enclosed volume of a plausible size (~0.06-0.09 m^3).
  double vol = 0;
  for (int f = 0; f < m.faces.rows(); ++f) {
    const Eigen::Vector3d a = m.v_template.row(m.faces(f, 0)), b = m.v_template.row(m.faces(f, 1)),
                          c = m.v_template.row(m.faces(f, 2));
    vol += a.dot(b.cross(c)) / 6.0;
  }
  EXPECT_GT(vol, 0.04);
  EXPECT_LT(vol, 0.12);
}

TEST(DefaultBody, SkeletonAndProportions) {
  const BodyModel& m = default_body_model();
  EXPECT_EQ(m.joint_names, kSmplNames);
  EXPECT_EQ(m.parents, kSmplParents);
  const double height = m.v_template.col(1).maxCoeff() - m.v_template.col(1).minCoeff();
  EXPECT_GT(height, 1.6);
  EXPECT_LT(height, 1.8);
  const Eigen::MatrixXd J = m.J_regressor * m.v_template;
  // Origin near the pelvis as in SMPL, soles near y = -1.15, left = +X, facing +Z.
  EXPECT_LT(J.row(0).norm(), 0.3);
  EXPECT_NEAR(m.v_template.col(1).minCoeff(), -1.15, 0.03);
  for (int l : {1, 4, 7, 10, 13, 16, 18, 20, 22}) EXPECT_GT(J(l, 0), 0.02) << kSmplNames[size_t(l)];
  EXPECT_GT(J(10, 2), J(7, 2));  // toes ahead of the ankle
  EXPECT_GT(J(22, 0), 0.6);      // arms out (T-pose-ish)
  EXPECT_NEAR(J(20, 1), J(16, 1), 0.1);
  // Regressor: rows sum to 1, joints mirror-symmetric, children above/below as expected.
  for (int j = 0; j < 24; ++j) EXPECT_NEAR(m.J_regressor.row(j).sum(), 1.0, 1e-9);
  for (int l : {1, 4, 7, 10, 13, 16, 18, 20, 22}) {
    EXPECT_NEAR(J(l, 0), -J(l + 1, 0), 1e-6);
    EXPECT_NEAR(J(l, 1), J(l + 1, 1), 1e-6);
  }
  // The regressor reproduces the designed skeleton (docs/body-models.md) exactly.
  EXPECT_LT((J.row(0) - Eigen::RowVector3d(0, -0.22, 0)).norm(), 1e-9);
  EXPECT_LT((J.row(20) - Eigen::RowVector3d(0.68, 0.18, -0.03)).norm(), 1e-9);
  EXPECT_LT((J.row(21) - Eigen::RowVector3d(-0.68, 0.18, -0.03)).norm(), 1e-9);
  EXPECT_LT((J.row(15) - Eigen::RowVector3d(0, 0.36, 0.02)).norm(), 1e-9);
  EXPECT_GT(J(15, 1), J(12, 1));
  EXPECT_GT(J(12, 1), J(9, 1));
  EXPECT_LT(J(7, 1), J(4, 1));
  EXPECT_LT(J(4, 1), J(1, 1));
}

TEST(DefaultBody, SkinWeightsAndParts) {
  const BodyModel& m = default_body_model();
  for (int v = 0; v < m.num_vertices(); ++v) {
    int nz = 0;
    for (int j = 0; j < 24; ++j) {
      EXPECT_GE(m.weights(v, j), 0.0);
      nz += m.weights(v, j) != 0.0;
    }
    ASSERT_LE(nz, 4) << "vertex " << v;
    ASSERT_NEAR(m.weights.row(v).sum(), 1.0, 1e-9);
  }
  ASSERT_EQ(int(m.part_labels.size()), m.num_vertices());
  const auto counts = part_vertex_counts(m.part_labels);
  for (int p = 0; p < kNumParts; ++p) EXPECT_GT(counts[size_t(p)], 50) << kPartNames[size_t(p)];
  // Left parts on the body's left (+X).
  for (int v = 0; v < m.num_vertices(); ++v) {
    const int p = m.part_labels[size_t(v)];
    if (p >= kLeftUpperArm && p != mirror_part(p)) {
      const bool left = (p % 2 == 1);
      EXPECT_EQ(m.v_template(v, 0) > 0, left)
          << "vertex " << v << " part " << kPartNames[size_t(p)];
    }
  }
  EXPECT_EQ(m.posedirs.rows(), 3 * m.num_vertices());
  EXPECT_EQ(m.posedirs.cols(), 9 * 23);
  EXPECT_TRUE(m.posedirs.isZero(0));
}

TEST(DefaultBody, MirrorSymmetry) {
  const BodyModel& m = default_body_model();
  const auto mm = mirror_map(m.v_template, 1e-6);
  int missing = 0, label_mismatch = 0;
  for (int v = 0; v < m.num_vertices(); ++v) {
    const int u = mm[size_t(v)];
    if (u < 0) {
      ++missing;
      continue;
    }
    if (m.part_labels[size_t(u)] != mirror_part(m.part_labels[size_t(v)])) ++label_mismatch;
  }
  EXPECT_EQ(missing, 0);
  EXPECT_EQ(label_mismatch, 0);
}

TEST(DefaultBody, ShapeDirectionsSpanRealVariation) {
  const BodyModel& m = default_body_model();
  ASSERT_GE(m.num_betas, 10);
  EXPECT_EQ(m.num_expression, 0);
  // Linearly independent directions.
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(m.shapedirs);
  const auto sv = svd.singularValues();
  EXPECT_GT(sv[m.num_betas - 1] / sv[0], 1e-3);
  auto shaped = [&](int i, double b) {
    BodyParams p;
    p.betas = Eigen::VectorXd::Zero(m.num_betas);
    p.betas[i] = b;
    return body_forward(m, p);
  };
  auto height = [](const BodyState& s) {
    return s.vertices.col(1).maxCoeff() - s.vertices.col(1).minCoeff();
  };
  const BodyState base = shaped(0, 0.0);
  EXPECT_GT(height(shaped(0, 2.0)) - height(base), 0.06);    // taller
  EXPECT_LT(height(shaped(0, -2.0)) - height(base), -0.06);  // shorter
  // Joints follow the shape through the regressor: longer legs lower the ankles.
  EXPECT_LT(shaped(4, 2.0).joints(7, 1), base.joints(7, 1) - 0.05);
  // Wider shoulders move the shoulder joints out; longer arms move the wrists out.
  EXPECT_GT(shaped(2, 2.0).joints(16, 0), base.joints(16, 0) + 0.02);
  EXPECT_GT(shaped(5, 2.0).joints(20, 0), base.joints(20, 0) + 0.03);
  // Girth grows the waist.
  auto waist_width = [](const BodyState& s) {
    double w = 0;
    for (int v = 0; v < s.vertices.rows(); ++v)
      if (std::abs(s.vertices(v, 1) + 0.07) < 0.02 && std::abs(s.vertices(v, 0)) < 0.3)
        w = std::max(w, std::abs(s.vertices(v, 0)));
    return w;
  };
  EXPECT_GT(waist_width(shaped(1, 2.0)), waist_width(base) + 0.01);
  // Every direction moves something by at least a centimetre at beta = 1.
  for (int i = 0; i < m.num_betas; ++i)
    EXPECT_GT((shaped(i, 1.0).vertices - base.vertices).rowwise().norm().maxCoeff(), 0.01) << i;
}

TEST(DefaultBody, DeterministicAndCached) {
  const BodyModel& a = default_body_model();
  const BodyModel& b = default_body_model();
  EXPECT_EQ(&a, &b);
  const BodyModel c = make_default_body_model();
  EXPECT_EQ(c.v_template, a.v_template);
  EXPECT_EQ(c.faces, a.faces);
  EXPECT_EQ(c.weights, a.weights);
}

TEST(DefaultBody, LoopSubdivisionCarriesRig) {
  const BodyModel& m = default_body_model();
  const Subdivision s = subdivide({m.v_template, m.faces}, 1, true);
  const int E = int(mesh_edges(m.faces).size());
  EXPECT_EQ(s.mesh.V.rows(), m.num_vertices() + E);
  EXPECT_EQ(s.mesh.F.rows(), 4 * m.faces.rows());
  EXPECT_TRUE(is_closed_manifold(s.mesh.F, int(s.mesh.V.rows())));
  const Eigen::MatrixXd W = s.S * m.weights;
  for (int v = 0; v < W.rows(); ++v) ASSERT_NEAR(W.row(v).sum(), 1.0, 1e-9);
  const auto labels = carry_labels(s.S, m.part_labels);
  for (int v = 0; v < m.num_vertices(); ++v) ASSERT_EQ(labels[size_t(v)], m.part_labels[size_t(v)]);
}

}  // namespace
}  // namespace ks
