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
#include "gltf/glb.hpp"
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
  // The mesh's vertices, joints and weights as the file holds them, skinned by kinesplat.
  const GlbDocument d = read_glb(glb);
  const auto& attrs = d.gltf["meshes"][0]["primitives"][0]["attributes"];
  const auto pos = d.read_floats(attrs["POSITION"]);
  const auto joints = d.read_uints(attrs["JOINTS_0"]);
  const auto weights = d.read_floats(attrs["WEIGHTS_0"]);
  const long W = long(pos.size() / 3);
  EXPECT_EQ(r["skinned"][2], W);
  EXPECT_EQ(r["points"][1], a.num_gaussians());
  EXPECT_EQ(r["textures"], 1);  // the base-colour texture
  for (int f : {0, 5, 11}) {
    const auto A = avatar_joint_transforms(a, walk.frames[size_t(f)]);
    const auto& p = r["frames"][std::to_string(f)];
    ASSERT_EQ(p.size(), size_t(3 * W));
    double worst = 0;
    for (size_t w = 0; w < size_t(W); ++w) {
      Eigen::Vector4d x(0, 0, 0, 0);
      const Eigen::Vector4d rest(pos[3 * w], pos[3 * w + 1], pos[3 * w + 2], 1);
      for (size_t s = 0; s < 4; ++s)
        x += double(weights[4 * w + s]) * (A[joints[4 * w + s]] * rest);
      for (size_t k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(x[long(k)] - p[3 * w + k].get<double>()));
    }
    EXPECT_LT(worst, 1e-4) << "frame " << f;  // float32 in the file and in three.js
    std::printf("three.js GLTFLoader, walk frame %d: largest vertex difference %.2e m\n", f, worst);
  }
}

}  // namespace
}  // namespace ks
