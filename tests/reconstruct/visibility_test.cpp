#include "reconstruct/visibility.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "core/error.hpp"

namespace ks {
namespace {

// A camera at the origin looking down +z, 200 x 200 pixels, 100 px focal length: at depth z a
// pixel is z / 100 m.
Camera test_camera() {
  Camera c;
  c.width = c.height = 200;
  c.fx = c.fy = 100;
  c.cx = c.cy = 100;
  return c;
}

// A square grid of points at depth z, spacing d, half-width h, optionally with a square hole of
// half-width `hole` in the middle. Returns the index of the first point added.
int add_plane(std::vector<float>* pts, float z, float h, float d, float hole = 0.f) {
  const int first = int(pts->size() / 3);
  for (float x = -h; x <= h + 1e-6f; x += d)
    for (float y = -h; y <= h + 1e-6f; y += d) {
      if (std::max(std::abs(x), std::abs(y)) < hole) continue;
      pts->insert(pts->end(), {x, y, z});
    }
  return first;
}

bool contains(const std::vector<int>& v, int i) {
  return std::binary_search(v.begin(), v.end(), i);
}

TEST(Visibility, HidesWhatLiesBehindASurfaceAndNothingNearItsEdges) {
  std::vector<float> pts;
  // Front plane at 2 m covering |x|, |y| <= 0.4 m (pixels 80 around the centre), points every
  // 1 cm (half a pixel); back plane at 2.5 m, wider, points every 2 cm.
  add_plane(&pts, 2.f, 0.4f, 0.01f);
  const int back = add_plane(&pts, 2.5f, 0.9f, 0.02f);
  const int n = int(pts.size() / 3);
  VisibilityOptions o;
  std::vector<int> vis;
  const int m = visible_points(pts.data(), nullptr, n, test_camera(), o, &vis);
  EXPECT_EQ(m, int(vis.size()));
  EXPECT_TRUE(std::is_sorted(vis.begin(), vis.end()));
  for (int i = 0; i < back; ++i) EXPECT_TRUE(contains(vis, i)) << "front point " << i;
  int hidden_inside = 0, back_inside = 0;
  for (int i = back; i < n; ++i) {
    const float x = pts[3 * size_t(i)], y = pts[3 * size_t(i) + 1];
    // Projected at 2.5 m, the front plane covers |x|, |y| < 0.5 m of the back plane.
    const float r = std::max(std::abs(x), std::abs(y));
    // Beside it (even by a fraction of a cell) nothing is hidden: a neighbouring cell sees the
    // back plane.
    if (r > 0.505f) {
      EXPECT_TRUE(contains(vis, i)) << "beside the front plane: " << x << " " << y;
    }
    if (r < 0.39f) {
      ++back_inside;
      hidden_inside += !contains(vis, i);
    }
  }
  EXPECT_EQ(hidden_inside, back_inside);
  EXPECT_GT(back_inside, 1000);
}

TEST(Visibility, SeesThroughAHoleAndKeepsPointsOffTheImage) {
  std::vector<float> pts;
  add_plane(&pts, 2.f, 0.4f, 0.01f, 0.2f);  // a 40 cm square hole
  const int back = add_plane(&pts, 2.5f, 0.45f, 0.02f);
  const int off = int(pts.size() / 3);
  pts.insert(pts.end(), {0.f, 0.f, -1.f});  // behind the camera
  pts.insert(pts.end(), {5.f, 0.f, 2.6f});  // off the image
  const int n = int(pts.size() / 3);
  std::vector<int> vis;
  visible_points(pts.data(), nullptr, n, test_camera(), VisibilityOptions{}, &vis);
  for (int i = back; i < off; ++i) {
    const float r = std::max(std::abs(pts[3 * size_t(i)]), std::abs(pts[3 * size_t(i) + 1]));
    if (r < 0.2f) {
      EXPECT_TRUE(contains(vis, i)) << "seen through the hole";
    }
    // The ring covers 0.25-0.5 m of the back plane; a cell (10 cm) inside it from each edge:
    if (r > 0.3f && r < 0.36f) {
      EXPECT_FALSE(contains(vis, i)) << "behind the front plane's ring";
    }
  }
  EXPECT_TRUE(contains(vis, off));
  EXPECT_TRUE(contains(vis, off + 1));
  // Within the depth margin nothing is hidden: the same planes 2 cm apart.
  std::vector<float> close;
  add_plane(&close, 2.f, 0.4f, 0.01f);
  add_plane(&close, 2.02f, 0.3f, 0.02f);
  visible_points(close.data(), nullptr, int(close.size() / 3), test_camera(), VisibilityOptions{},
                 &vis);
  EXPECT_EQ(vis.size(), close.size() / 3);
}

// A point behind the front plane a cell and a bit inside its edge is hidden as a point, but not
// as a Gaussian whose footprint (3 sigma, 6 px here) reaches past the edge.
TEST(Visibility, AWideFootprintReachingPastTheEdgeIsNotHidden) {
  std::vector<float> pts;
  add_plane(&pts, 2.f, 0.4f, 0.01f);  // its edge 20 px right of the centre
  const int p = int(pts.size() / 3);
  pts.insert(pts.end(), {0.38f, 0.f, 2.5f});  // 15.2 px right of the centre, 60 cm behind
  const int n = int(pts.size() / 3);
  std::vector<float> sig(size_t(n), 0.f);
  std::vector<int> vis;
  visible_points(pts.data(), sig.data(), n, test_camera(), VisibilityOptions{}, &vis);
  EXPECT_FALSE(contains(vis, p));
  sig[size_t(p)] = 0.05f;
  visible_points(pts.data(), sig.data(), n, test_camera(), VisibilityOptions{}, &vis);
  EXPECT_TRUE(contains(vis, p));
  EXPECT_EQ(int(vis.size()), n);
}

TEST(Visibility, RejectsBadOptions) {
  std::vector<float> pts = {0.f, 0.f, 2.f};
  std::vector<int> vis;
  VisibilityOptions o;
  o.cell = 0;
  EXPECT_THROW(visible_points(pts.data(), nullptr, 1, test_camera(), o, &vis), Error);
  o.cell = 4;
  o.reach = -1;
  EXPECT_THROW(visible_points(pts.data(), nullptr, 1, test_camera(), o, &vis), Error);
}

}  // namespace
}  // namespace ks
