// The UV atlas (src/mesh/uv_atlas.hpp): charts that keep every face's orientation, rectangles
// that do not overlap, vertices copied only where charts meet, and clear errors.
#include <gtest/gtest.h>

#include <cmath>

#include "body/body_model.hpp"
#include "core/error.hpp"
#include "mesh/trimesh.hpp"
#include "mesh/uv_atlas.hpp"

namespace ks {
namespace {

double signed_area(const UvAtlas& a, long f) {
  const float* p0 = &a.uv[2 * size_t(a.faces(f, 0))];
  const float* p1 = &a.uv[2 * size_t(a.faces(f, 1))];
  const float* p2 = &a.uv[2 * size_t(a.faces(f, 2))];
  return double(p1[0] - p0[0]) * (p2[1] - p0[1]) - double(p1[1] - p0[1]) * (p2[0] - p0[0]);
}

TEST(UvAtlas, BodyTemplateChartsKeepFacesAndDoNotOverlap) {
  const BodyModel& m = default_body_model();
  const UvAtlas a = build_uv_atlas(m.v_template, m.faces);
  const long F = m.faces.rows();
  ASSERT_EQ(a.faces.rows(), F);
  ASSERT_EQ(a.uv.size(), 2 * a.source.size());
  ASSERT_EQ(a.face_chart.size(), size_t(F));
  EXPECT_GT(a.charts, 8);  // a closed body cannot be one chart
  // Every face names the same mesh vertices as before.
  for (long f = 0; f < F; ++f)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(a.source[size_t(a.faces(f, k))], m.faces(f, k));
  // Copies only on chart borders: far fewer than one vertex per face corner.
  EXPECT_LT(double(a.source.size()), 1.6 * double(m.v_template.rows()));
  // UVs inside the texture, every face with the same orientation and a real area.
  for (float u : a.uv) {
    EXPECT_GT(u, 0.f);
    EXPECT_LT(u, 1.f);
  }
  int positive = 0;
  for (long f = 0; f < F; ++f) positive += signed_area(a, f) > 0;
  EXPECT_TRUE(positive == 0 || positive == F) << positive << " of " << F;
  // At least the scale asked for (the body fits in the largest texture without shrinking).
  double edge = 0;
  for (long f = 0; f < F; ++f)
    for (int k = 0; k < 3; ++k)
      edge += (m.v_template.row(m.faces(f, k)) - m.v_template.row(m.faces(f, (k + 1) % 3))).norm();
  edge /= double(3 * F);
  EXPECT_GE(a.texels_per_metre * edge, UvAtlasOptions{}.texels_per_edge);
  UvAtlasOptions exact;
  exact.fill = false;
  EXPECT_NEAR(build_uv_atlas(m.v_template, m.faces, exact).texels_per_metre * edge,
              exact.texels_per_edge, 1e-9);
  // Each texel centre lies in faces of at most one chart (the gutter keeps charts apart).
  const int S = a.size;
  std::vector<int> chart_at(size_t(S) * S, -1);
  int clashes = 0;
  for (long f = 0; f < F; ++f) {
    double x[3], y[3];
    for (int k = 0; k < 3; ++k) {
      x[k] = a.uv[2 * size_t(a.faces(f, k))] * S;
      y[k] = a.uv[2 * size_t(a.faces(f, k)) + 1] * S;
    }
    const double ar = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
    for (int ty = int(std::min({y[0], y[1], y[2]})); ty <= int(std::max({y[0], y[1], y[2]})); ++ty)
      for (int tx = int(std::min({x[0], x[1], x[2]})); tx <= int(std::max({x[0], x[1], x[2]}));
           ++tx) {
        const double qx = tx + 0.5, qy = ty + 0.5;
        bool inside = true;
        for (int k = 0; k < 3; ++k) {
          const int i = (k + 1) % 3, j = (k + 2) % 3;
          inside &= ((x[i] - qx) * (y[j] - qy) - (y[i] - qy) * (x[j] - qx)) / ar >= 0;
        }
        if (!inside) continue;
        int& c = chart_at[size_t(ty) * S + size_t(tx)];
        if (c >= 0 && c != a.face_chart[size_t(f)]) ++clashes;
        c = a.face_chart[size_t(f)];
      }
  }
  EXPECT_EQ(clashes, 0);
}

TEST(UvAtlas, FlatSheetIsOneChartWithoutCopies) {
  // A 10 x 10 grid in the z = 0 plane.
  const int n = 10;
  Eigen::MatrixXd V((n + 1) * (n + 1), 3);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) V.row(i * (n + 1) + j) << 0.01 * j, 0.01 * i, 0;
  Eigen::MatrixXi F(2 * n * n, 3);
  int f = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int a = i * (n + 1) + j, b = a + 1, c = a + n + 1, d = c + 1;
      F.row(f++) << a, b, d;
      F.row(f++) << a, d, c;
    }
  const UvAtlas a = build_uv_atlas(V, F);
  EXPECT_EQ(a.charts, 1);
  EXPECT_EQ(a.source.size(), size_t(V.rows()));
  EXPECT_EQ(a.size, UvAtlasOptions{}.min_size);
  // The projection is a similarity: UV distances are 3D distances times the scale.
  for (long e = 0; e < F.rows(); ++e) {
    const int p = a.faces(e, 0), q = a.faces(e, 1);
    const double du = (a.uv[2 * size_t(p)] - a.uv[2 * size_t(q)]) * a.size,
                 dv = (a.uv[2 * size_t(p) + 1] - a.uv[2 * size_t(q) + 1]) * a.size;
    EXPECT_NEAR(std::hypot(du, dv), (V.row(F(e, 0)) - V.row(F(e, 1))).norm() * a.texels_per_metre,
                1e-3);
  }
}

TEST(UvAtlas, LargeMeshShrinksToTheLargestTexture) {
  const BodyModel& m = default_body_model();
  UvAtlasOptions o;
  o.texels_per_edge = 200;  // would need a texture far beyond max_size
  o.max_size = 1024;
  const UvAtlas a = build_uv_atlas(m.v_template, m.faces, o);
  EXPECT_EQ(a.size, 1024);
  for (float u : a.uv) EXPECT_LT(u, 1.f);
}

TEST(UvAtlas, BadInputIsAClearError) {
  const BodyModel& m = default_body_model();
  EXPECT_THROW(build_uv_atlas(Eigen::MatrixXd(0, 3), Eigen::MatrixXi(0, 3)), Error);
  Eigen::MatrixXi bad = m.faces;
  bad(0, 0) = int(m.v_template.rows());
  EXPECT_THROW(build_uv_atlas(m.v_template, bad), Error);
  UvAtlasOptions o;
  o.max_normal_angle_deg = 95;
  EXPECT_THROW(build_uv_atlas(m.v_template, m.faces, o), Error);
  o = {};
  o.min_size = 300;
  EXPECT_THROW(build_uv_atlas(m.v_template, m.faces, o), Error);
  o = {};
  o.texels_per_edge = 0;
  EXPECT_THROW(build_uv_atlas(m.v_template, m.faces, o), Error);
}

}  // namespace
}  // namespace ks
