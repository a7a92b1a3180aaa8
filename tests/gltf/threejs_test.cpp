// three.js's GLTFLoader (the viewer's pinned three, `make deps`) reads an exported GLB in Node:
// the skinned mesh with every bone, the splats as points, every motion as a clip of the right
// duration, and its AnimationMixer + skinning pose the mesh where kinesplat's skinning transforms
// put it. Skips, saying why, where node or the viewer's packages are missing.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "../temp_dir.hpp"
#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/fileio.hpp"
#include "gltf/gltf_export.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

TEST(GltfThreejs, GltfLoaderPosesTheMeshAsKinesplatDoes) {
  const fs::path viewer = fs::path(KS_SOURCE_DIR) / "viewer";
  if (std::system("command -v node >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "node is not installed: `make deps` installs it";
  if (!fs::exists(viewer / "node_modules" / "three" / "package.json"))
    GTEST_SKIP() << "the viewer's npm packages (three) are not installed ("
                 << viewer / "node_modules"
                 << "): run `make deps`";
  PlainAvatarOptions opt;
  opt.posedirs = false;
  const Avatar a = avatar_from_body(default_body_model(), Eigen::VectorXd::Zero(2), opt);
  const Motion walk = builtin_motion("walk", 12), wave = builtin_motion("wave", 8);
  test::TempDir tmp("gltf_three");
  const std::string glb = (tmp.path() / "a.glb").string();
  export_gltf(glb, a, {walk, wave});
  const std::string out = (tmp.path() / "three.json").string();
  const std::string cmd = "node '" +
                          (fs::path(KS_SOURCE_DIR) / "tests/gltf/three_pose.mjs").string() + "' '" +
                          viewer.string() + "' '" + glb + "' walk " + std::to_string(walk.fps) +
                          " 0 5 11 > '" + out + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  nlohmann::json r;
  try {
    r = nlohmann::json::parse(read_file_text(out));
  } catch (const std::exception&) {
    FAIL() << "three.js did not answer (exit " << rc << "):\n" << read_file_text(out);
  }
  ASSERT_EQ(r["clips"].size(), 2u);
  EXPECT_EQ(r["clips"][0][0], "walk");
  EXPECT_NEAR(r["clips"][0][1].get<double>(), 11 / walk.fps, 1e-5);
  EXPECT_EQ(r["clips"][0][2], a.num_joints() + 1);
  EXPECT_NEAR(r["clips"][1][1].get<double>(), 7 / wave.fps, 1e-5);
  EXPECT_EQ(r["skinned"][0], "avatar_mesh");
  EXPECT_EQ(r["skinned"][1], a.num_joints());
  // The textured mesh's vertices: the atlas's copies of the template's.
  const UvAtlas atlas =
      build_uv_atlas(a.template_vertices, a.template_faces, GltfExportOptions{}.texture.atlas);
  const long W = long(atlas.source.size());
  EXPECT_EQ(r["skinned"][2], W);
  EXPECT_EQ(r["points"][1], a.num_gaussians());
  EXPECT_EQ(r["textures"], 1);  // the base-colour texture
  const BakedVertexAttributes baked = bake_vertex_attributes(a);
  for (int f : {0, 5, 11}) {
    const auto A = avatar_joint_transforms(a, walk.frames[size_t(f)]);
    const auto& p = r["frames"][std::to_string(f)];
    ASSERT_EQ(p.size(), size_t(3 * W));
    double worst = 0;
    for (long w = 0; w < W; ++w) {
      const long v = atlas.source[size_t(w)];
      Eigen::Vector4d x(0, 0, 0, 0);
      const Eigen::Vector4d rest(a.template_vertices(v, 0), a.template_vertices(v, 1),
                                 a.template_vertices(v, 2), 1);
      for (int s = 0; s < 4; ++s)
        x += double(baked.weights[4 * size_t(v) + size_t(s)]) *
             (A[size_t(baked.joints[4 * size_t(v) + size_t(s)])] * rest);
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(x[k] - p[3 * size_t(w) + size_t(k)].get<double>()));
    }
    EXPECT_LT(worst, 1e-4) << "frame " << f;  // float32 in the file and in three.js
    std::printf("three.js GLTFLoader, walk frame %d: largest vertex difference %.2e m\n", f, worst);
  }
}

}  // namespace
}  // namespace ks
