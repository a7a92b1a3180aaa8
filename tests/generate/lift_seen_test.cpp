// The lift's step 2 (generate/lift_seen.hpp): colour from the photo where it sees the surface.
#include <gtest/gtest.h>

#include "core/math.hpp"
#include "generate/lift_seen.hpp"
#include "lift_case.hpp"

namespace ks {

TEST(LiftSeen, InnerMaskDropsTheOutline) {
  const test::LiftCase c(1);
  const Image inner = lift::inner_mask(c.mask, c.options);
  ASSERT_EQ(inner.width, c.mask.width);
  ASSERT_EQ(inner.height, c.mask.height);
  int outline = 0, kept = 0;
  for (int y = 1; y + 1 < c.mask.height; ++y)
    for (int x = 1; x + 1 < c.mask.width; ++x) {
      const bool in = c.mask.at(x, y, 0) >= 0.5f;
      if (!in) {
        EXPECT_LT(inner.at(x, y, 0), 0.5f);  // nothing grows
        continue;
      }
      const bool edge = c.mask.at(x - 1, y, 0) < 0.5f || c.mask.at(x + 1, y, 0) < 0.5f ||
                        c.mask.at(x, y - 1, 0) < 0.5f || c.mask.at(x, y + 1, 0) < 0.5f;
      if (edge) {
        EXPECT_LT(inner.at(x, y, 0), 0.5f) << x << "," << y;
        ++outline;
      } else {
        kept += inner.at(x, y, 0) >= 0.5f;
      }
    }
  EXPECT_GT(outline, 50);
  EXPECT_GT(kept, 500);
}

TEST(LiftSeen, SeenVerticesTakeThePhotosColour) {
  const test::LiftCase c(1);
  const LiftOptions& o = c.options;
  const Camera& cam = c.fit.camera;
  const Image inner = lift::inner_mask(c.mask, o);
  const Eigen::MatrixXd& V = c.body.posed.vertices;
  const Eigen::MatrixXd& N = c.body.posed_normals;
  const lift::SeenColour s = lift::seen_colour(c.photo, inner, V, N, c.body.render, cam, o);
  ASSERT_EQ(s.colour.rows(), V.rows());
  ASSERT_EQ(s.weight.size(), V.rows());
  const Eigen::Vector3d eye = cam.centre();
  long seen = 0;
  for (long i = 0; i < V.rows(); ++i) {
    const Eigen::Vector3d p = V.row(i).transpose();
    const double cosv = -N.row(i).dot((p - eye).normalized());
    if (s.weight(i) == 0) {
      EXPECT_EQ(s.colour.row(i).norm(), 0.0);
      continue;
    }
    ++seen;
    // Facing the camera, inside the inner mask, weighted by how squarely, the photo's colour.
    EXPECT_GE(cosv, o.visible_cos);
    const Eigen::Vector2d uv = cam.project(p);
    EXPECT_TRUE(lift::in_mask(inner, uv.x(), uv.y()));
    EXPECT_EQ(s.weight(i), smoothstep(o.visible_cos, o.full_view_cos, cosv));
    EXPECT_EQ(s.colour.row(i), lift::sample_rgb(c.photo, uv.x(), uv.y()).transpose());
  }
  // About the half that faces the camera is seen.
  EXPECT_GT(seen, V.rows() / 5);
  EXPECT_LT(seen, V.rows() * 3 / 5);
  // A uniform photo: every seen vertex gets its colour.
  Image grey(c.photo.width, c.photo.height, 3, 0.f);
  for (int y = 0; y < grey.height; ++y)
    for (int x = 0; x < grey.width; ++x) {
      grey.at(x, y, 0) = 0.25f;
      grey.at(x, y, 1) = 0.5f;
      grey.at(x, y, 2) = 0.75f;
    }
  const lift::SeenColour g = lift::seen_colour(grey, inner, V, N, c.body.render, cam, o);
  for (long i = 0; i < V.rows(); ++i)
    if (g.weight(i) > 0) {
      EXPECT_NEAR(g.colour(i, 0), 0.25, 1e-6);
      EXPECT_NEAR(g.colour(i, 1), 0.5, 1e-6);
      EXPECT_NEAR(g.colour(i, 2), 0.75, 1e-6);
    }
}

TEST(LiftSeen, AnEmptyMaskSeesNothing) {
  const test::LiftCase c(1);
  const Image none(c.mask.width, c.mask.height, 1, 0.f);
  const lift::SeenColour s =
      lift::seen_colour(c.photo, none, c.body.posed.vertices, c.body.posed_normals, c.body.render,
                        c.fit.camera, c.options);
  EXPECT_EQ(s.weight.maxCoeff(), 0.0);
}

}  // namespace ks
