#include "meshrender/meshrender.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

namespace {

Camera simple_camera(int w = 64, int h = 48, double f = 100.0) {
  Camera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = f;
  c.cx = 0.5 * w;
  c.cy = 0.5 * h;
  return c;  // R = I, t = 0: looks down +z, x right, y down
}

double sum(const Image& img, int ch = 0) {
  double s = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) s += img.at(x, y, ch);
  return s;
}

// A point in the image -> the camera-space point at depth z.
Eigen::Vector3d unproject(const Camera& c, double u, double v, double z) {
  return {(u - c.cx) / c.fx * z, (v - c.cy) / c.fy * z, z};
}

double shoelace(const std::vector<Eigen::Vector2d>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const auto& q = p[i];
    const auto& r = p[(i + 1) % p.size()];
    a += q.x() * r.y() - q.y() * r.x();
  }
  return 0.5 * std::abs(a);
}

}  // namespace

TEST(MeshRender, TriangleCoverageMatchesArea) {
  const Camera cam = simple_camera();
  // A triangle with non-integer projected corners, slanted in depth.
  const std::vector<Eigen::Vector2d> px = {{5.3, 4.7}, {58.2, 12.9}, {21.6, 43.1}};
  const double zs[3] = {2.0, 2.7, 3.4};
  Eigen::MatrixXd V(3, 3);
  for (int k = 0; k < 3; ++k) V.row(k) = unproject(cam, px[k].x(), px[k].y(), zs[k]).transpose();
  Eigen::MatrixXi F(1, 3);
  F << 0, 1, 2;
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  MeshRenderOptions opt;
  opt.supersample = 8;
  const auto out = render_mesh(cam, in, opt);
  const double area = shoelace(px);
  // Coverage error is bounded by the perimeter times the sample spacing.
  EXPECT_NEAR(sum(out.mask), area, 0.02 * area);
  // Pixels well inside are fully covered, far outside empty; rgb = grey inside, white outside.
  EXPECT_FLOAT_EQ(out.mask.at(28, 20, 0), 1.0f);
  EXPECT_FLOAT_EQ(out.mask.at(60, 40, 0), 0.0f);
  EXPECT_NEAR(out.rgb.at(28, 20, 0), 0.7f, 1e-6);
  EXPECT_FLOAT_EQ(out.rgb.at(60, 40, 0), 1.0f);
}

TEST(MeshRender, QuadOnPixelGridIsExactAndWatertight) {
  const Camera cam = simple_camera();
  // Projected quad spanning columns 7..56 and rows 4..39 exactly; split into a fan of 8
  // triangles around an interior point so that many shared edges cross pixel centres.
  const double z = 2.5;
  const std::vector<Eigen::Vector2d> ring = {{7, 4},   {32, 4},  {57, 4}, {57, 22},
                                             {57, 40}, {32, 40}, {7, 40}, {7, 22}};
  Eigen::MatrixXd V(9, 3);
  for (int k = 0; k < 8; ++k) V.row(k) = unproject(cam, ring[k].x(), ring[k].y(), z).transpose();
  V.row(8) = unproject(cam, 30.5, 20.5, z).transpose();  // centre on a pixel centre
  Eigen::MatrixXi F(8, 3);
  for (int k = 0; k < 8; ++k) F.row(k) << 8, k, (k + 1) % 8;
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  for (int ss : {1, 2, 3}) {
    MeshRenderOptions opt;
    opt.supersample = ss;
    const auto out = render_mesh(cam, in, opt);
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const bool inside = x >= 7 && x < 57 && y >= 4 && y < 40;
        ASSERT_FLOAT_EQ(out.mask.at(x, y, 0), inside ? 1.0f : 0.0f)
            << "pixel " << x << "," << y << " S=" << ss;
      }
  }
}

TEST(MeshRender, ProjectedQuadAreaWithPerspective) {
  Camera cam = simple_camera(96, 96, 120.0);
  // A unit square tilted 40 degrees about the vertical axis, 3 m away.
  const double a = 40.0 * M_PI / 180.0;
  Eigen::MatrixXd V(4, 3);
  const double hs = 0.5;
  const Eigen::Vector3d centre(0.1, -0.05, 3.0);
  const Eigen::Vector3d ex(std::cos(a), 0, std::sin(a)), ey(0, 1, 0);
  V.row(0) = (centre - hs * ex - hs * ey).transpose();
  V.row(1) = (centre + hs * ex - hs * ey).transpose();
  V.row(2) = (centre + hs * ex + hs * ey).transpose();
  V.row(3) = (centre - hs * ex + hs * ey).transpose();
  Eigen::MatrixXi F(2, 3);
  F << 0, 1, 2, 0, 2, 3;
  std::vector<Eigen::Vector2d> px;
  for (int k = 0; k < 4; ++k) px.push_back(cam.project(V.row(k).transpose()));
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  MeshRenderOptions opt;
  opt.supersample = 6;
  opt.want_depth = true;
  const auto out = render_mesh(cam, in, opt);
  const double area = shoelace(px);
  EXPECT_NEAR(sum(out.mask), area, 0.02 * area);
  // Depth at the centre pixel of the projected centre: the ray through it hits the plane.
  const Eigen::Vector2d pc = cam.project(centre);
  const int x = int(std::floor(pc.x())), y = int(std::floor(pc.y()));
  const Eigen::Vector3d ray((x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0);
  const Eigen::Vector3d n = ex.cross(ey);
  const double zhit = n.dot(centre) / n.dot(ray);
  // Depth is the nearest sample's z: within the pixel's depth range.
  EXPECT_NEAR(out.depth.at(x, y, 0), zhit, 0.02);
}

TEST(MeshRender, DepthOrderOfOverlappingTriangles) {
  const Camera cam = simple_camera();
  Eigen::MatrixXd V(6, 3);
  // Near triangle (z = 2, red) and far triangle (z = 3, green), overlapping in the middle.
  const std::vector<Eigen::Vector2d> a = {{5, 5}, {45, 8}, {20, 40}};
  const std::vector<Eigen::Vector2d> b = {{15, 10}, {60, 20}, {30, 45}};
  for (int k = 0; k < 3; ++k) {
    V.row(k) = unproject(cam, a[k].x(), a[k].y(), 2.0).transpose();
    V.row(3 + k) = unproject(cam, b[k].x(), b[k].y(), 3.0).transpose();
  }
  Eigen::MatrixXd C(6, 3);
  C << 1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0;
  for (int order = 0; order < 2; ++order) {
    Eigen::MatrixXi F(2, 3);
    if (order == 0)
      F << 0, 1, 2, 3, 4, 5;
    else
      F << 3, 4, 5, 0, 1, 2;
    MeshRenderInput in;
    in.vertices = &V;
    in.faces = &F;
    in.colors = &C;
    MeshRenderOptions opt;
    opt.want_depth = true;
    const auto out = render_mesh(cam, in, opt);
    // (25, 20) is inside both: the near (red) one wins.
    EXPECT_FLOAT_EQ(out.rgb.at(25, 20, 0), 1.0f);
    EXPECT_FLOAT_EQ(out.rgb.at(25, 20, 1), 0.0f);
    EXPECT_NEAR(out.depth.at(25, 20, 0), 2.0, 1e-5);
    // (50, 22) is only inside the far one.
    EXPECT_FLOAT_EQ(out.rgb.at(50, 22, 1), 1.0f);
    EXPECT_NEAR(out.depth.at(50, 22, 0), 3.0, 1e-5);
    EXPECT_FLOAT_EQ(out.depth.at(62, 2, 0), 0.0f);
  }
}

TEST(MeshRender, PerspectiveCorrectInterpolation) {
  const Camera cam = simple_camera(64, 64, 80.0);
  // A strongly slanted triangle; colour channel 0 = world x, channel 1 = world z / 10.
  Eigen::MatrixXd V(3, 3);
  V << -1.0, -0.8, 1.5, 1.2, -0.6, 6.0, -0.2, 1.0, 3.0;
  Eigen::MatrixXi F(1, 3);
  F << 0, 1, 2;
  Eigen::MatrixXd C(3, 3);
  for (int k = 0; k < 3; ++k) C.row(k) << V(k, 0), V(k, 2) / 10.0, 0.0;
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  in.colors = &C;
  MeshRenderOptions opt;
  opt.want_depth = true;
  opt.background = Eigen::Vector3d::Zero();
  const auto out = render_mesh(cam, in, opt);
  const Eigen::Vector3d p0 = V.row(0), p1 = V.row(1), p2 = V.row(2);
  const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
  int tested = 0;
  for (int y = 0; y < 64; y += 3)
    for (int x = 0; x < 64; x += 3) {
      if (out.mask.at(x, y, 0) < 1.0f) continue;
      const Eigen::Vector3d ray((x + 0.5 - cam.cx) / cam.fx, (y + 0.5 - cam.cy) / cam.fy, 1.0);
      const Eigen::Vector3d hit = ray * (n.dot(p0) / n.dot(ray));
      EXPECT_NEAR(out.rgb.at(x, y, 0), hit.x(), 2e-4) << x << "," << y;
      EXPECT_NEAR(out.rgb.at(x, y, 1), hit.z() / 10.0, 2e-4) << x << "," << y;
      EXPECT_NEAR(out.depth.at(x, y, 0), hit.z(), 1e-3);
      ++tested;
    }
  EXPECT_GT(tested, 20);
}

TEST(MeshRender, OffCentrePrincipalPoint) {
  Camera cam = simple_camera(64, 48, 90.0);
  cam.cx = 17.3;
  cam.cy = 31.8;
  // Rotate and translate the camera too: look at a point from an angle.
  cam =
      Camera::look_at({0.6, 0.4, -2.0}, {0.1, 0.2, 0.3}, {0, 1, 0}, 64, 48, 90.0, 90.0, 17.3, 31.8);
  // A small square around the target: its projection is centred on (cx, cy).
  const Eigen::Vector3d c(0.1, 0.2, 0.3);
  const Eigen::Vector3d right = cam.R.row(0).transpose(), down = cam.R.row(1).transpose();
  const double h = 0.15;
  Eigen::MatrixXd V(4, 3);
  V.row(0) = (c - h * right - h * down).transpose();
  V.row(1) = (c + h * right - h * down).transpose();
  V.row(2) = (c + h * right + h * down).transpose();
  V.row(3) = (c - h * right + h * down).transpose();
  Eigen::MatrixXi F(2, 3);
  F << 0, 1, 2, 0, 2, 3;
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  MeshRenderOptions opt;
  opt.supersample = 8;
  const auto out = render_mesh(cam, in, opt);
  double sx = 0, sy = 0, sm = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const double m = out.mask.at(x, y, 0);
      sx += m * (x + 0.5);
      sy += m * (y + 0.5);
      sm += m;
    }
  ASSERT_GT(sm, 4.0);
  // Sample quantisation shifts the centroid by at most a fraction of the sample spacing (1/8).
  EXPECT_NEAR(sx / sm, 17.3, 0.03);
  EXPECT_NEAR(sy / sm, 31.8, 0.03);
  // The projection of the target lies in column floor(cx), row floor(cy).
  EXPECT_FLOAT_EQ(out.mask.at(17, 31, 0), 1.0f);
}

TEST(MeshRender, NormalsLabelsAndLighting) {
  const Camera cam = simple_camera();
  Eigen::MatrixXd V(4, 3);
  // A quad facing the camera (normal towards -z in camera space), counter-clockwise seen
  // from the camera side.
  V << -0.5, -0.4, 2.0, -0.5, 0.4, 2.0, 0.5, 0.4, 2.0, 0.5, -0.4, 2.0;
  Eigen::MatrixXi F(2, 3);
  F << 0, 1, 2, 0, 2, 3;
  const Eigen::MatrixXd n = vertex_normals(V, F);
  EXPECT_NEAR(n(0, 2), -1.0, 1e-12);
  std::vector<int> labels = {3, 3, 7, 7};  // left half 3, right half 7
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  in.labels = &labels;
  MeshRenderOptions opt;
  opt.want_normal = true;
  opt.want_labels = true;
  opt.lighting = true;
  opt.ambient = 0.25;
  opt.light_dir = Eigen::Vector3d(0, 0, -1);  // from the camera
  auto out = render_mesh(cam, in, opt);
  EXPECT_NEAR(out.normal.at(32, 24, 2), -1.0f, 1e-6);
  EXPECT_EQ(out.labels[24 * 64 + 12], 3);
  EXPECT_EQ(out.labels[24 * 64 + 52], 7);
  EXPECT_EQ(out.labels[2 * 64 + 2], -1);
  EXPECT_NEAR(out.rgb.at(32, 24, 0), 0.7f, 1e-5);  // head-on light: full albedo
  opt.light_dir = Eigen::Vector3d(1, 0, -1);       // 45 degrees
  out = render_mesh(cam, in, opt);
  EXPECT_NEAR(out.rgb.at(32, 24, 0), 0.7f * (0.25f + 0.75f * std::sqrt(0.5f)), 1e-5);
  const Image nrgb = normal_to_rgb(out.normal);
  EXPECT_NEAR(nrgb.at(32, 24, 2), 1.0f, 1e-6);
  const Image lrgb = labels_to_rgb(out.labels, 64, 48);
  EXPECT_FLOAT_EQ(lrgb.at(2, 2, 0), 1.0f);
  // Back-face culling: the quad seen from behind disappears.
  Eigen::MatrixXi Fb(2, 3);
  Fb << 0, 2, 1, 0, 3, 2;
  in.faces = &Fb;
  opt.cull_backfaces = true;
  out = render_mesh(cam, in, opt);
  EXPECT_EQ(sum(out.mask), 0.0);
  in.faces = &F;
  out = render_mesh(cam, in, opt);
  EXPECT_GT(sum(out.mask), 100.0);
}

TEST(MeshRender, TextureAndNearPlaneClipping) {
  const Camera cam = simple_camera();
  // A floor-like quad reaching behind the camera: clipped at the near plane.
  Eigen::MatrixXd V(4, 3);
  V << -1, 0.5, -1.0, 1, 0.5, -1.0, 1, 0.5, 4.0, -1, 0.5, 4.0;
  Eigen::MatrixXi F(2, 3);
  F << 0, 2, 1, 0, 3, 2;
  // 2 x 1 texture: left texel red, right texel blue; u = 0 at x = -1, 1 at x = 1.
  Image tex(2, 1, 3, 0.0f);
  tex.at(0, 0, 0) = 1.0f;
  tex.at(1, 0, 2) = 1.0f;
  Eigen::MatrixXd uv(4, 2);
  uv << 0, 0, 1, 0, 1, 1, 0, 1;
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  in.texture = &tex;
  in.uvs = &uv;
  MeshRenderOptions opt;
  opt.near = 0.1;
  const auto out = render_mesh(cam, in, opt);
  // The floor (y = 0.5 below the camera) covers the bottom of the image up to the horizon of
  // its far edge: row v = cy + f * 0.5 / 4 = 36.5.
  EXPECT_FLOAT_EQ(out.mask.at(32, 47, 0), 1.0f);
  EXPECT_FLOAT_EQ(out.mask.at(32, 37, 0), 1.0f);
  EXPECT_FLOAT_EQ(out.mask.at(32, 35, 0), 0.0f);
  // Left of centre is x < 0 -> u < 0.5 -> reddish; right of centre bluish.
  EXPECT_GT(out.rgb.at(10, 45, 0), 0.9f);
  EXPECT_LT(out.rgb.at(10, 45, 2), 0.1f);
  EXPECT_GT(out.rgb.at(54, 45, 2), 0.9f);
}

TEST(MeshRender, RejectsBadInput) {
  const Camera cam = simple_camera();
  Eigen::MatrixXd V(3, 3);
  V << 0, 0, 1, 1, 0, 1, 0, 1, 1;
  Eigen::MatrixXi F(1, 3);
  F << 0, 1, 3;
  MeshRenderInput in;
  in.vertices = &V;
  in.faces = &F;
  EXPECT_THROW(render_mesh(cam, in), Error);
  F << 0, 1, 2;
  Eigen::MatrixXd C(2, 3);
  in.colors = &C;
  EXPECT_THROW(render_mesh(cam, in), Error);
  in.colors = nullptr;
  MeshRenderOptions opt;
  opt.supersample = 0;
  EXPECT_THROW(render_mesh(cam, in, opt), Error);
  Camera bad = cam;
  bad.width = 0;
  EXPECT_THROW(render_mesh(bad, in), Error);
}

}  // namespace ks
