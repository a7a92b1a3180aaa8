// The colour bake (src/gltf/color_bake.hpp): the texture over the UV atlas shows the Gaussians'
// colours where they are, and the exported GLB carries it as its base-colour texture.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "avatar/from_body.hpp"
#include "body/body_model.hpp"
#include "gltf/color_bake.hpp"
#include "gltf/glb.hpp"
#include "gltf/gltf_export.hpp"
#include "io/image_decode.hpp"
#include "raster/sh.hpp"

namespace ks {
namespace {

// The default body's plain avatar, its Gaussians red on the body's left (x > 0), blue elsewhere.
Avatar two_colour_avatar() {
  PlainAvatarOptions opt;
  opt.posedirs = false;
  Avatar a = avatar_from_body(default_body_model(), Eigen::VectorXd::Zero(2), opt);
  const int K = a.gaussians.coeffs();
  for (size_t i = 0; i < a.gaussians.size(); ++i) {
    const bool left = a.gaussians.means[3 * i] > 0;
    const float rgb[3] = {left ? 1.f : 0.f, 0.f, left ? 0.f : 1.f};
    for (int c = 0; c < 3; ++c)
      a.gaussians.sh[i * size_t(K) * 3 + size_t(c)] = float((rgb[c] - 0.5) / sh::kC0);
  }
  return a;
}

// The texel under a face's centroid.
const float* centroid_texel(const BakedTexture& t, long f) {
  double u = 0, v = 0;
  for (int k = 0; k < 3; ++k) {
    u += t.atlas.uv[2 * size_t(t.atlas.faces(f, k))] / 3.0;
    v += t.atlas.uv[2 * size_t(t.atlas.faces(f, k)) + 1] / 3.0;
  }
  const int x = int(u * t.atlas.size), y = int(v * t.atlas.size);
  return &t.image.data[(size_t(y) * size_t(t.image.width) + size_t(x)) * 3];
}

TEST(ColorBake, TextureShowsTheGaussiansColours) {
  const Avatar a = two_colour_avatar();
  const auto members = gaussians_per_vertex(a);
  const BakedVertexAttributes vc = bake_vertex_attributes(a, members);
  const BakedTexture t = bake_texture(a, a.template_vertices, vc, members);
  ASSERT_EQ(t.image.width, t.atlas.size);
  ASSERT_EQ(t.image.channels, 3);
  int left = 0, right = 0;
  for (long f = 0; f < a.template_faces.rows(); ++f) {
    double xmin = 1e9, xmax = -1e9;
    for (int k = 0; k < 3; ++k) {
      xmin = std::min(xmin, a.template_vertices(a.template_faces(f, k), 0));
      xmax = std::max(xmax, a.template_vertices(a.template_faces(f, k), 0));
    }
    // Faces well inside one side: nowhere near the splats of the other.
    const float* c = centroid_texel(t, f);
    if (xmin > 0.05) {
      EXPECT_GT(c[0], 0.95f) << f;
      EXPECT_LT(c[2], 0.05f) << f;
      ++left;
    } else if (xmax < -0.05) {
      EXPECT_LT(c[0], 0.05f) << f;
      EXPECT_GT(c[2], 0.95f) << f;
      ++right;
    }
  }
  EXPECT_GT(left, 1000);
  EXPECT_GT(right, 1000);
}

TEST(ColorBake, GlbCarriesTheTexture) {
  const Avatar a = two_colour_avatar();
  GltfExportOptions o;
  o.splats = false;
  o.template_surface = true;  // the bake below is over the template
  const GlbDocument d = parse_glb(avatar_gltf(a, {}, o), "tex.glb");
  const auto& g = d.gltf;
  const auto& prim = g["meshes"][0]["primitives"][0];
  ASSERT_TRUE(prim["attributes"].contains("TEXCOORD_0"));
  EXPECT_FALSE(prim["attributes"].contains("COLOR_0"));
  EXPECT_EQ(g["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"], 0);
  EXPECT_EQ(g["textures"][0]["source"], 0);
  ASSERT_EQ(g["images"][0]["mimeType"], "image/png");
  // The image decodes to the bake, 8-bit.
  const auto& view = g["bufferViews"][g["images"][0]["bufferView"].get<size_t>()];
  const size_t off = view["byteOffset"], len = view["byteLength"];
  ASSERT_LE(off + len, d.bin.size());
  const cv::Mat img = decode_image_file(
      std::vector<uint8_t>(d.bin.begin() + long(off), d.bin.begin() + long(off + len)), "tex");
  const auto members = gaussians_per_vertex(a);
  const BakedTexture t =
      bake_texture(a, a.template_vertices, bake_vertex_attributes(a, members), members);
  ASSERT_EQ(img.cols, t.atlas.size);
  ASSERT_EQ(img.rows, t.atlas.size);
  ASSERT_EQ(img.type(), CV_8UC3);
  double worst = 0;
  for (int y = 0; y < img.rows; y += 7)
    for (int x = 0; x < img.cols; x += 7)
      for (int c = 0; c < 3; ++c)  // OpenCV's BGR
        worst = std::max(
            worst, std::abs(img.at<cv::Vec3b>(y, x)[2 - c] / 255.0 - double(t.image.at(x, y, c))));
  EXPECT_LE(worst, 0.5 / 255 + 1e-6);
  // The UVs and positions are the atlas's copies of the template's vertices.
  const auto uv = d.read_floats(prim["attributes"]["TEXCOORD_0"]);
  const auto pos = d.read_floats(prim["attributes"]["POSITION"]);
  ASSERT_EQ(uv.size(), t.atlas.uv.size());
  for (size_t w = 0; w < t.atlas.source.size(); ++w) {
    EXPECT_FLOAT_EQ(uv[2 * w], t.atlas.uv[2 * w]);
    for (int k = 0; k < 3; ++k)
      EXPECT_FLOAT_EQ(pos[3 * w + size_t(k)], float(a.template_vertices(t.atlas.source[w], k)));
  }
}

}  // namespace
}  // namespace ks
