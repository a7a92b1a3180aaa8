// Density-control mesh operations on the real default body template.
#include <gtest/gtest.h>

#include <random>

#include "body/body_model.hpp"
#include "mesh/trimesh.hpp"
#include "reconstruct/density_ops.hpp"

namespace ks {
namespace {

TEST(DensityBody, SplitAndCollapseKeepTheBodyManifold) {
  const BodyModel& m = default_body_model();
  const int N = m.num_vertices();
  const bool closed = is_closed_manifold(m.faces, N);
  const int chi = euler_characteristic(m.faces, N);
  std::mt19937 rng(7);
  std::vector<uint8_t> fsel(m.faces.rows(), 0);
  for (auto& s : fsel) s = (rng() % 20) == 0;
  const MeshEdit sp = split_faces(m.faces, N, fsel);
  EXPECT_EQ(is_closed_manifold(sp.faces, sp.num_vertices()), closed);
  EXPECT_EQ(euler_characteristic(sp.faces, sp.num_vertices()), chi);
  const Eigen::MatrixXd V1 = sp.S * m.v_template;
  std::vector<uint8_t> cand(sp.num_vertices(), 0);
  for (int r : sp.new_rows) cand[r] = (rng() % 3) == 0;
  const MeshEdit co = collapse_vertices(V1, sp.faces, cand);
  EXPECT_LT(co.num_vertices(), sp.num_vertices());
  EXPECT_EQ(is_closed_manifold(co.faces, co.num_vertices()), closed);
  EXPECT_EQ(euler_characteristic(co.faces, co.num_vertices()), chi);
  for (int v = 0; v < sp.num_vertices(); ++v)
    if (co.old_to_new[v] < 0) {
      EXPECT_TRUE(cand[v]) << v;
    }
}

}  // namespace
}  // namespace ks
